# Writes the build-information header read by core/common/build_info.cpp. Run as a script on every build
# (cmake -P, from the nirslam_build_info target in the top-level CMakeLists.txt), so the git commit is
# the one the binary was really built from; configure_file() rewrites the header only when a value
# changed, so an unchanged tree recompiles nothing.
#
# In: SOURCE_DIR, TEMPLATE, OUTPUT, NIRSLAM_BUILD_TYPE, NIRSLAM_BUILD_COMPILER, NIRSLAM_IMGUI_VERSION.
cmake_policy(VERSION 3.25)

set(NIRSLAM_GIT_DESCRIBE "")
set(NIRSLAM_GIT_COMMIT "")
find_package(Git QUIET)
if(GIT_FOUND AND EXISTS "${SOURCE_DIR}/.git")
  execute_process(COMMAND "${GIT_EXECUTABLE}" -C "${SOURCE_DIR}" describe --always --dirty --tags
                  OUTPUT_VARIABLE NIRSLAM_GIT_DESCRIBE OUTPUT_STRIP_TRAILING_WHITESPACE
                  RESULT_VARIABLE describe_result ERROR_QUIET)
  execute_process(COMMAND "${GIT_EXECUTABLE}" -C "${SOURCE_DIR}" rev-parse HEAD
                  OUTPUT_VARIABLE NIRSLAM_GIT_COMMIT OUTPUT_STRIP_TRAILING_WHITESPACE
                  RESULT_VARIABLE commit_result ERROR_QUIET)
  # A source export or a repository without commits: say nothing rather than something wrong.
  if(NOT describe_result EQUAL 0 OR NOT commit_result EQUAL 0)
    set(NIRSLAM_GIT_DESCRIBE "")
    set(NIRSLAM_GIT_COMMIT "")
  endif()
endif()

# string(TIMESTAMP) honours SOURCE_DATE_EPOCH. Day only: a time of day would rebuild every build.
string(TIMESTAMP NIRSLAM_BUILD_DATE "%Y-%m-%d" UTC)

configure_file("${TEMPLATE}" "${OUTPUT}" @ONLY)
