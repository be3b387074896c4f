# Install rules and the exported package (included by the top-level CMakeLists.txt after every
# target exists).
#
#   cmake --install build [--prefix DIR]
#
#   bin/      npfkct-server npfkct-drive npfkct-bench npfkct-train npfkct-sim-robot
#             npfkct-scenegen, npfkct-client (the Python client's CLI)
#   lib/      libnpfkct_common.a libnpfkct_solver.a libnpfkct_object_search.a
#             libnpfkct_render.a libnpfkct_perception.a libnpfkct_robot.a libnpfkct_api.a
#             libnpfkct_client.a
#   lib/cmake/npfkct/   npfkctConfig.cmake, npfkctConfigVersion.cmake, npfkctTargets.cmake
#   include/npfkct/{common,solver,object_search,render,perception,robot,api,client}/
#   share/npfkct/models/      the shipped filter model (npfkct-server's default --model-dir)
#   share/npfkct/scenarios/   the scenario files (npfkct-drive --scenario)
#   share/npfkct/schemas/     JSON Schemas and openapi.yaml
#   share/npfkct/python/      the Python client package (bin/npfkct-client runs it)
#
# Each rule names its component, which is the Debian package that carries it
# (cmake/npfkct_package.cmake): server (npfkct-server), dev (libnpfkct-dev), python
# (python3-npfkct-client). `cmake --install` installs them all.
include(CMakePackageConfigHelpers)

set(NPFKCT_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/npfkct)
set(NPFKCT_INSTALL_DATADIR ${CMAKE_INSTALL_DATADIR}/npfkct)

install(PROGRAMS
  $<TARGET_FILE:npfkct-server> $<TARGET_FILE:npfkct-drive> $<TARGET_FILE:npfkct-sim-robot>
  $<TARGET_FILE:npfkct-scenegen>
  DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT server)
install(PROGRAMS $<TARGET_FILE:npfkct-bench> DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT dev)
if(NPFKCT_WITH_TORCH)
  install(PROGRAMS $<TARGET_FILE:npfkct-train> DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT dev)
endif()

# The libraries for embedding, with their public headers: the solver, the object-search model,
# and the typed C++ client with the API layer it speaks through (whose types are those of the
# object-search model and of perception; the API layer draws belief pictures with render).
set_target_properties(npfkct_common PROPERTIES EXPORT_NAME common)
set_target_properties(npfkct_solver PROPERTIES EXPORT_NAME solver)
set_target_properties(npfkct_object_search PROPERTIES EXPORT_NAME object_search)
set_target_properties(npfkct_render PROPERTIES EXPORT_NAME render)
set_target_properties(npfkct_perception PROPERTIES EXPORT_NAME perception)
set_target_properties(npfkct_robot PROPERTIES EXPORT_NAME robot)
set_target_properties(npfkct_api PROPERTIES EXPORT_NAME api)
set_target_properties(npfkct_client PROPERTIES EXPORT_NAME client)
install(TARGETS npfkct_common npfkct_solver npfkct_object_search npfkct_render npfkct_perception
                npfkct_robot npfkct_api npfkct_client
  EXPORT npfkctTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY common/include/npfkct solver/include/npfkct object_search/include/npfkct
                  render/include/npfkct perception/include/npfkct robot/include/npfkct
                  server/api/include/npfkct
                  clients/cpp/include/npfkct
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev FILES_MATCHING PATTERN "*.h")
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/common/include/npfkct/common/version.h
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/npfkct/common COMPONENT dev)
install(EXPORT npfkctTargets NAMESPACE npfkct:: DESTINATION ${NPFKCT_INSTALL_CMAKEDIR}
  COMPONENT dev)
configure_package_config_file(cmake/npfkctConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/npfkctConfig.cmake
  INSTALL_DESTINATION ${NPFKCT_INSTALL_CMAKEDIR}
  PATH_VARS NPFKCT_INSTALL_DATADIR)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/npfkctConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/npfkctConfig.cmake
              ${CMAKE_CURRENT_BINARY_DIR}/npfkctConfigVersion.cmake
  DESTINATION ${NPFKCT_INSTALL_CMAKEDIR} COMPONENT dev)

# Data: models, scenarios, schemas.
# The shipped model: its .pt (with libtorch) and its weight file (.npw, which any build loads).
if(NPFKCT_WITH_TORCH)
  install(FILES filter/model/filter.pt DESTINATION ${NPFKCT_INSTALL_DATADIR}/models
    COMPONENT server)
endif()
install(FILES filter/model/filter.npw DESTINATION ${NPFKCT_INSTALL_DATADIR}/models
  COMPONENT server)
install(DIRECTORY scenarios/ DESTINATION ${NPFKCT_INSTALL_DATADIR}/scenarios COMPONENT server
  FILES_MATCHING PATTERN "*.json")
install(DIRECTORY schemas/ DESTINATION ${NPFKCT_INSTALL_DATADIR}/schemas COMPONENT server)

# The Python client: its package, and bin/npfkct-client that runs its CLI from there (pip install
# ./clients/python installs the same package into a Python environment instead).
install(DIRECTORY clients/python/npfkct_client DESTINATION ${NPFKCT_INSTALL_DATADIR}/python
  COMPONENT python FILES_MATCHING PATTERN "*.py" PATTERN "__pycache__" EXCLUDE)
file(RELATIVE_PATH NPFKCT_PYTHON_FROM_BIN ${CMAKE_INSTALL_FULL_BINDIR}
     ${CMAKE_INSTALL_FULL_DATADIR}/npfkct/python)
configure_file(cmake/npfkct_cli.in ${CMAKE_CURRENT_BINARY_DIR}/npfkct-client @ONLY)
install(PROGRAMS ${CMAKE_CURRENT_BINARY_DIR}/npfkct-client DESTINATION ${CMAKE_INSTALL_BINDIR}
  COMPONENT python)
