"""npfkct_ros: the FindObject action server in front of the npfkct planning server, and the
simulated robot's bridge to ROS. The generated messages live in npfkct_ros.msg."""
