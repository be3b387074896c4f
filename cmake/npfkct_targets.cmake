# Helpers every module's CMakeLists.txt uses.

# npfkct_add_program(TARGET SOURCES...): a program of the project. Every program is built into
# BUILD_DIR/bin, whichever folder it lives in, so that scripts, tests and users find them in one
# place.
function(npfkct_add_program target)
  add_executable(${target} ${ARGN})
  set_target_properties(${target} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bin)
endfunction()

# npfkct_add_unit_tests(TARGET SOURCES...): a GoogleTest executable of a module's unit tests,
# linked with gtest_main, its tests registered with ctest under the label "unit"
# (ctest -L unit runs them alone). Link the module under test with target_link_libraries.
function(npfkct_add_unit_tests target)
  add_executable(${target} ${ARGN})
  target_link_libraries(${target} PRIVATE GTest::gtest_main Threads::Threads)
  gtest_discover_tests(${target} DISCOVERY_TIMEOUT 120 PROPERTIES LABELS unit)
endfunction()
