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

# Seconds the longest suites took in a full `ctest -j2` (2026-12-06, AMD
# EPYC, busy). ctest starts the costliest first; without these a fresh clone
# (no Testing/Temporary/CTestCostData.txt yet) ran them in declaration order,
# the 4-minute ErrorProbe as 151st of 155, and one core idled at the end
# (a fresh-clone run of .ci/run: ctest took 835 s for 1,501 s of tests).
set(ddhgs_suite_costs
  test_reliability.ErrorProbe=324 test_app.RigCli=194 test_app.DenoiserCli=92
  test_app.ProcessCli=79 test_app.OrthoCli=60 test_app.TrainCli=56
  test_reliability.EarlyChecks=49 test_app.PriorCli=48 test_app.BlocksCli=41
  test_app.ReportCli=40 test_app.AblateCli=38 test_reliability.OutputSafety=31
  test_reliability.UserFiles=28 test_app.BandLayoutsCli=24 test_app.RigRefinementCli=23
  test_app.ExportCli=20 test_reliability.FullDisk=20 test_app.LightCli=19
  test_app.EvalCli=19 test_app.InfoCli=18 test_app.BandPerViewCli=18)

foreach(suite IN LISTS suites)
  set(name "${ddhgs_suite_prefix}.${suite}")
  add_test("${name}" "${ddhgs_suite_exe}" "--gtest_filter=${suite}.*")
  foreach(entry IN LISTS ddhgs_suite_costs)
    if(entry MATCHES "^${name}=([0-9]+)$")
      set_tests_properties("${name}" PROPERTIES COST "${CMAKE_MATCH_1}")
    endif()
  endforeach()
  set_tests_properties("${name}" PROPERTIES
    ENVIRONMENT "${ddhgs_suite_environment}"
    TIMEOUT "${ddhgs_suite_timeout}"
    SKIP_REGULAR_EXPRESSION "${ddhgs_suite_skip_regex}"
    WORKING_DIRECTORY "${ddhgs_suite_workdir}")
endforeach()
