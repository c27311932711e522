# Writes OUTPUT (a header defining LIFMCR_GIT_REVISION) from the git state of
# SOURCE_DIR; rewritten only when the revision changes, so a build that
# changes nothing recompiles nothing. Run at every build by lifmcr_git_revision.
execute_process(
  COMMAND git -C "${SOURCE_DIR}" describe --always --dirty --abbrev=12
  OUTPUT_VARIABLE revision
  OUTPUT_STRIP_TRAILING_WHITESPACE
  ERROR_QUIET
  RESULT_VARIABLE result)
if(NOT result EQUAL 0 OR revision STREQUAL "")
  set(revision "unknown")
endif()
set(text "#pragma once\n// Generated at build time by apps/git_revision.cmake.\n#define LIFMCR_GIT_REVISION \"${revision}\"\n")
set(old "")
if(EXISTS "${OUTPUT}")
  file(READ "${OUTPUT}" old)
endif()
if(NOT old STREQUAL text)
  file(WRITE "${OUTPUT}" "${text}")
endif()
