# Debian packages by CPack (included by the top-level CMakeLists.txt after the install rules):
#
#   cd build && cpack -G DEB        # or: cmake --build build --target package
#
#   npfkct-server          npfkct-server, npfkct-drive, npfkct-sim-robot, npfkct-scenegen, the
#                          shipped filter model, the scenarios and schemas, a systemd unit
#                          (npfkct-server.service, not enabled) and /etc/default/npfkct-server
#   libnpfkct-dev          the static libraries, headers and CMake package (find_package(npfkct)),
#                          npfkct-bench and npfkct-train
#   python3-npfkct-client  the Python client (importable by Debian's python3) and npfkct-client
#
# Runtime dependencies come from dpkg-shlibdeps (the shared libraries the programs link), so they
# follow the build machine's Debian release; the -dev package depends on the -dev packages its
# CMake package finds. tests/test_packages.py installs them on a fresh Debian 12 root.
# The ROS package is built by catkin in a workspace (docs/ros.md), not packaged here.

# Files only a package holds: absolute or system locations a `cmake --install --prefix DIR`
# must not write.
install(FILES deploy/debian/npfkct-server.service DESTINATION /lib/systemd/system
  COMPONENT server EXCLUDE_FROM_ALL)
install(FILES deploy/debian/npfkct-server.default DESTINATION /etc/default
  RENAME npfkct-server COMPONENT server EXCLUDE_FROM_ALL)
install(FILES deploy/debian/npfkct.pth DESTINATION lib/python3/dist-packages
  COMPONENT python EXCLUDE_FROM_ALL)
foreach(pair server:npfkct-server dev:libnpfkct-dev python:python3-npfkct-client)
  string(REPLACE ":" ";" pair "${pair}")
  list(GET pair 0 component)
  list(GET pair 1 package)
  install(FILES LICENSE DESTINATION ${CMAKE_INSTALL_DATADIR}/doc/${package} RENAME copyright
    COMPONENT ${component} EXCLUDE_FROM_ALL)
  install(FILES README.md CHANGELOG.md DESTINATION ${CMAKE_INSTALL_DATADIR}/doc/${package}
    COMPONENT ${component} EXCLUDE_FROM_ALL)
endforeach()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME npfkct)
set(CPACK_PACKAGE_VENDOR npfkct)
set(CPACK_PACKAGE_CONTACT "npfkct maintainers <npfkct@example.org>")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_PACKAGE_DIRECTORY ${CMAKE_BINARY_DIR}/packages)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL server dev python)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_STRIP_FILES ON)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_HOMEPAGE "https://www.apache.org/licenses/LICENSE-2.0")
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)

set(CPACK_DEBIAN_SERVER_PACKAGE_NAME npfkct-server)
set(CPACK_DEBIAN_SERVER_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_SERVER_PACKAGE_DEPENDS "curl")
set(CPACK_DEBIAN_SERVER_PACKAGE_RECOMMENDS "python3-npfkct-client, jq")
set(CPACK_DEBIAN_SERVER_PACKAGE_CONTROL_EXTRA ${CMAKE_CURRENT_SOURCE_DIR}/deploy/debian/conffiles)
set(CPACK_COMPONENT_SERVER_DESCRIPTION "npfkct planning server for robot object search
An HTTP/JSON server that keeps, per robot, a belief over where a target object is and plans
the next best hybrid action (a camera configuration, or declaring or removing an object)
with NPF-kCT, beside POMCP-family baselines. With the simulated robot, the episode driver,
the shipped filter model, scenarios and a systemd unit.")

set(CPACK_DEBIAN_DEV_PACKAGE_NAME libnpfkct-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS
  "npfkct-server (= ${PROJECT_VERSION}-1), libeigen3-dev, nlohmann-json3-dev, libcurl4-openssl-dev, libopencv-dev, libpcl-dev, liburdfdom-dev, liborocos-kdl-dev, libspdlog-dev")
set(CPACK_COMPONENT_DEV_DESCRIPTION "npfkct libraries and headers for embedding
The solver library (POMCP family and k-center clustering tree), the object-search model, the
API layer and the typed C++ client, as a CMake package (find_package(npfkct)), with
npfkct-bench and npfkct-train.")

set(CPACK_DEBIAN_PYTHON_PACKAGE_NAME python3-npfkct-client)
set(CPACK_DEBIAN_PYTHON_PACKAGE_ARCHITECTURE all)
set(CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS "python3 (>= 3.9), python3-requests")
set(CPACK_DEBIAN_PYTHON_PACKAGE_SUGGESTS "python3-yaml")
set(CPACK_COMPONENT_PYTHON_DESCRIPTION "Python client of the npfkct planning server
Typed calls, session objects and the npfkct-client command line.")

include(CPack)
