import sys

from npfkct_client.cli import main

sys.exit(main())
