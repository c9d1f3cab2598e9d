# Writes OUT (a header defining QD_GIT_REVISION) from the source tree's git HEAD, at build time, so
# provenance.toml names the revision that was built, not the one that was configured. The file is
# only rewritten when the revision changes, so an unchanged tree rebuilds nothing.
execute_process(COMMAND git rev-parse --short=12 HEAD WORKING_DIRECTORY ${SRC}
                OUTPUT_VARIABLE rev OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
if(rev)
  execute_process(COMMAND git diff --quiet HEAD -- WORKING_DIRECTORY ${SRC} RESULT_VARIABLE dirty ERROR_QUIET)
  if(dirty)
    string(APPEND rev "-dirty")  # local changes to tracked files: the revision alone does not name the code
  endif()
else()
  set(rev "unknown")
endif()
set(content "#define QD_GIT_REVISION \"${rev}\"\n")
if(EXISTS ${OUT})
  file(READ ${OUT} old)
endif()
if(NOT "${old}" STREQUAL "${content}")
  file(WRITE ${OUT} "${content}")
endif()
