#!/usr/bin/env bash
# The npfkct-ros Debian package: this catkin package built and installed under /usr as Debian's
# own ROS packages are (catkin's binary-package mode: no setup files of a workspace), staged with
# DESTDIR and packed with dpkg-deb. The node imports the npfkct client from python3-npfkct-client
# (cpack's package), which it depends on, so the copy catkin installs with it is left out.
#
# Usage: clients/ros/npfkct_ros/build_deb.sh WORKSPACE OUT_DIR
#   WORKSPACE: a catkin workspace whose src/ holds this package (tests/test_ros.py makes one); it
#   gets a build-deb/ and devel-deb/ of its own. Writes OUT_DIR/npfkct-ros_VERSION-1_all.deb.
set -euo pipefail
WS="$(cd "$1" && pwd)"
mkdir -p "$2"
OUT="$(cd "$2" && pwd)"
PACKAGE_DIR="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
VERSION=$(sed -n 's:.*<version>\(.*\)</version>.*:\1:p' "$PACKAGE_DIR/package.xml")
STAGE="$WS/deb-stage"
rm -rf "$STAGE"
# Debian's ROS lives in /usr/bin/python3's packages: catkin must run with it.
export PATH="/usr/bin:/bin:$PATH"
(cd "$WS" && catkin_make --build build-deb -DCATKIN_DEVEL_PREFIX="$WS/devel-deb" \
  -DCMAKE_INSTALL_PREFIX=/usr -DCATKIN_BUILD_BINARY_PACKAGE=1 \
  -DPYTHON_EXECUTABLE=/usr/bin/python3 > "$WS/build-deb.log" 2>&1) ||
  { tail -30 "$WS/build-deb.log" >&2; exit 1; }
make -C "$WS/build-deb" install DESTDIR="$STAGE" >> "$WS/build-deb.log" 2>&1 ||
  { tail -30 "$WS/build-deb.log" >&2; exit 1; }
rm -rf "$STAGE"/usr/lib/python3/dist-packages/npfkct_client
find "$STAGE" -name __pycache__ -prune -exec rm -rf {} +
mkdir -p "$STAGE/DEBIAN" "$STAGE/usr/share/doc/npfkct-ros"
cp "$PACKAGE_DIR/../../../LICENSE" "$STAGE/usr/share/doc/npfkct-ros/copyright"
SIZE=$(du -sk --exclude=DEBIAN "$STAGE" | cut -f1)
cat > "$STAGE/DEBIAN/control" <<EOF
Package: npfkct-ros
Version: $VERSION-1
Architecture: all
Section: science
Priority: optional
Maintainer: npfkct maintainers <npfkct@example.org>
Installed-Size: $SIZE
Depends: python3-npfkct-client (>= $VERSION), python3-rospy, python3-roslaunch, python3-actionlib,
 python3-actionlib-msgs, python3-tf2-ros, python3-genpy, python3-std-msgs, python3-geometry-msgs,
 python3-sensor-msgs, python3-nav-msgs, python3-trajectory-msgs, python3-visualization-msgs
Description: ROS 1 front of the npfkct planning server
 A FindObject action server that drives one object-search session per goal (plan, execute
 through FollowJointTrajectory, a base goal and ObjectCommand, observe typed 3D detections
 paired with tf at their stamp), RViz markers of the belief and the next view, and a bridge
 that plays the simulated robot over the same interfaces.
EOF
dpkg-deb --root-owner-group --build "$STAGE" "$OUT/npfkct-ros_${VERSION}-1_all.deb" > /dev/null
echo "$OUT/npfkct-ros_${VERSION}-1_all.deb"
