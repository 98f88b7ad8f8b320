# Registers one ctest test per GoogleTest suite of a test executable, at ctest
# time (included through the TEST_INCLUDE_FILES directory property; see
# tests/CMakeLists.txt). One process per suite instead of one per test: every
# process of ours pays LibTorch's start-up (0.55-0.95 s of CPU: its operator
# registry and the relocations of the libraries it pulls in): 583 tests paid
# it 583 times, 118 suites pay it 118 times (ctest 0.70x the wall time;
# docs/benchmarks.md). The ctest test "test_io.PlyReader" runs
# `test_io --gtest_filter=PlyReader.*`; one test of it runs with
# `build/tests/test_io --gtest_filter=PlyReader.RoundTrip`.
#
# Variables set by the including file: ddhgs_suite_exe (the executable),
# ddhgs_suite_prefix (the ctest name's prefix), ddhgs_suite_environment,
# ddhgs_suite_timeout, ddhgs_suite_skip_regex, ddhgs_suite_workdir.

if(NOT EXISTS "${ddhgs_suite_exe}")
  # Not built (a partial build): one failing test says so.
  add_test("${ddhgs_suite_prefix}.NOT_BUILT" "${ddhgs_suite_exe}")
  return()
endif()

execute_process(
  COMMAND "${ddhgs_suite_exe}" --gtest_list_tests
  WORKING_DIRECTORY "${ddhgs_suite_workdir}"
  OUTPUT_VARIABLE listing
  ERROR_VARIABLE listing_errors
  RESULT_VARIABLE listing_status
  TIMEOUT 120)
if(NOT listing_status EQUAL 0)
  # The listing itself failed (a crash in a static initialiser, say): a
  # test that reruns it fails and shows why, rather than no tests at all.
  add_test("${ddhgs_suite_prefix}.LISTING_FAILED" "${ddhgs_suite_exe}" --gtest_list_tests)
  return()
endif()

# The listing is a suite line ("Suite." or "Prefix/Suite.", no indent)
# followed by its tests' lines (indented); only the suite lines matter.
string(REPLACE "\n" ";" lines "${listing}")
set(suites "")
foreach(line IN LISTS lines)
  if(line MATCHES "^([^ #][^ ]*)\\.$")
    list(APPEND suites "${CMAKE_MATCH_1}")
  endif()
endforeach()
list(REMOVE_DUPLICATES suites)

foreach(suite IN LISTS suites)
  set(name "${ddhgs_suite_prefix}.${suite}")
  add_test("${name}" "${ddhgs_suite_exe}" "--gtest_filter=${suite}.*")
  set_tests_properties("${name}" PROPERTIES
    ENVIRONMENT "${ddhgs_suite_environment}"
    TIMEOUT "${ddhgs_suite_timeout}"
    SKIP_REGULAR_EXPRESSION "${ddhgs_suite_skip_regex}"
    WORKING_DIRECTORY "${ddhgs_suite_workdir}")
endforeach()
