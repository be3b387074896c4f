#!/usr/bin/env bash
# The slim image: npfkct-server, npfkct-sim-robot and npfkct-drive built without libtorch (the
# filter runs the shipped model's weights, filter.npw, with Eigen), the shared objects they load
# and nothing else (not their packages: Debian's OpenCV core package pulls Mesa and LLVM, its
# image codecs GDAL, its libtorch FFmpeg and OpenCV's video modules, none of which the programs
# load), the model, the scenarios and schemas, and busybox for a shell and the health check.
# Built from scratch with buildah (an image archive; `docker load`/`podman load` take it), then a
# demo episode runs inside it (buildah run, chroot isolation): the server on loopback and
# npfkct-drive through Loose1. Prints and writes OUT/slim.json: the root's and the archive's
# sizes, the packages' root for comparison, and the demo's outcome.
#
# Usage: docker/slim/build.sh [OUT (default build-slim/image)]
#        env: BUILD_DIR (default build-slim), the torch-less build it makes or reuses
# Needs root, buildah and busybox-static (Debian packages). Run the image:
#   docker load -i OUT/npfkct-slim.tar   (or: podman load -i ...)
#   docker run -p 8080:8080 -e NPFKCT_API_KEY=choose-one npfkct-slim
#   docker run --rm --entrypoint /bin/sh npfkct-slim -c 'npfkct-server --port 8081 & sleep 1;
#     npfkct-drive --server http://127.0.0.1:8081 --scenario /usr/share/npfkct/scenarios/loose1.json'
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
BUILD_DIR="${BUILD_DIR:-$ROOT/build-slim}"
OUT="${1:-$BUILD_DIR/image}"
PROGRAMS=(npfkct-server npfkct-sim-robot npfkct-drive)
for tool in buildah busybox cmake; do
  command -v "$tool" > /dev/null || { echo "build.sh: $tool is not installed" >&2; exit 2; }
done

cmake -S "$ROOT" -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DNPFKCT_WITH_TORCH=OFF \
  -DNPFKCT_BUILD_TESTS=OFF > /dev/null
cmake --build "$BUILD_DIR" -j "$(nproc)" --target "${PROGRAMS[@]}" > /dev/null

rm -rf "$OUT"
ROOTFS="$OUT/rootfs"
mkdir -p "$ROOTFS"/usr/{bin,lib,lib64,share/npfkct/models} "$ROOTFS"/{etc,tmp,var/lib/npfkct}
# Debian 12's merged /usr: /bin, /lib and /lib64 are links into /usr.
ln -s usr/bin "$ROOTFS/bin"
ln -s usr/lib "$ROOTFS/lib"
ln -s usr/lib64 "$ROOTFS/lib64"
chmod 1777 "$ROOTFS/tmp"
for p in "${PROGRAMS[@]}"; do
  install -m 755 -s "$BUILD_DIR/bin/$p" "$ROOTFS/usr/bin/$p"
done
# The shared objects the programs load, each at the path the loader looks for it (its soname
# link resolved to the file).
libs=$(for p in "${PROGRAMS[@]}"; do ldd "$BUILD_DIR/bin/$p"; done |
  awk '/=>/ && $3 ~ /^\// {print $3} /^\t\/lib64\// {print $1}' | sort -u)
for lib in $libs; do
  dest="$ROOTFS$(readlink -f "$(dirname "$lib")")/$(basename "$lib")"
  mkdir -p "$(dirname "$dest")"
  cp -L "$lib" "$dest"
done
install -m 755 "$(command -v busybox)" "$ROOTFS/usr/bin/busybox"
for applet in sh wget sleep kill; do ln -s busybox "$ROOTFS/usr/bin/$applet"; done
cp "$ROOT/filter/model/filter.npw" "$ROOTFS/usr/share/npfkct/models/"
cp -r "$ROOT/scenarios" "$ROOT/schemas" "$ROOTFS/usr/share/npfkct/"
cp "$ROOT/LICENSE" "$ROOTFS/usr/share/npfkct/"
printf 'root:x:0:0:root:/root:/bin/sh\nnpfkct:x:10001:10001::/var/lib/npfkct:/bin/sh\n' \
  > "$ROOTFS/etc/passwd"
printf 'root:x:0:\nnpfkct:x:10001:\n' > "$ROOTFS/etc/group"
chown 10001:10001 "$ROOTFS/var/lib/npfkct"
root_bytes=$(du -sxb "$ROOTFS" | cut -f1)
lib_count=$(echo "$libs" | wc -l)

# The image, from scratch.
export STORAGE_DRIVER=vfs
ctr=$(buildah from scratch)
trap 'buildah rm "$ctr" > /dev/null 2>&1 || true' EXIT
buildah copy "$ctr" "$ROOTFS" / > /dev/null
buildah config --user npfkct --workingdir /var/lib/npfkct --port 8080 --volume /var/lib/npfkct \
  --env PATH=/usr/bin \
  --healthcheck 'CMD wget -q -O /dev/null http://127.0.0.1:8080/healthz' \
  --healthcheck-interval 10s \
  --entrypoint '["/usr/bin/npfkct-server", "--host", "0.0.0.0", "--port", "8080", "--state-dir", "/var/lib/npfkct"]' \
  --label org.opencontainers.image.title=npfkct-slim \
  --label org.opencontainers.image.licenses=Apache-2.0 "$ctr"
# Docker's image format (OCI's has no health check); `docker load` and `podman load` read it.
buildah commit --format docker "$ctr" docker-archive:"$OUT/npfkct-slim.tar":npfkct-slim:latest \
  > /dev/null
archive_bytes=$(stat -c %s "$OUT/npfkct-slim.tar")

# The demo: inside the image, the server on a free loopback port and npfkct-drive through Loose1.
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
demo=$(buildah run --isolation chroot --user npfkct "$ctr" /bin/sh -c "
  npfkct-server --port $port --state-dir /tmp/state > /tmp/server.log 2>&1 &
  for i in \$(seq 100); do wget -q -O /dev/null http://127.0.0.1:$port/healthz 2>/dev/null && break; sleep 0.1; done
  npfkct-drive --server http://127.0.0.1:$port --scenario /usr/share/npfkct/scenarios/loose1.json \
    --budget-ms 500
  kill %1" 2>&1 | tail -8)
echo "$demo"
outcome=$(echo "$demo" | grep '^outcome:' || true)

python3 - "$OUT/slim.json" "$root_bytes" "$archive_bytes" "$lib_count" "$outcome" <<'EOF'
import json, sys
out, root, archive, libs, outcome = sys.argv[1:]
figures = {"root_mib": round(int(root) / 2**20, 1), "archive_mib": round(int(archive) / 2**20, 1),
           "shared_objects": int(libs), "demo": outcome or "failed"}
json.dump(figures, open(out, "w"), indent=1)
print(json.dumps(figures))
EOF
[[ -n "$outcome" ]]
