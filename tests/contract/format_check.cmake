# Every C++ source is formatted as .clang-format says (clang-format from scripts/setup).
#   cmake -DSOURCE_DIR=... -DCLANG_FORMAT=... -P format_check.cmake
set(sources "")
foreach(dir core drivers acquisition processing storage mocks services apps tests bench examples)
  file(GLOB_RECURSE found "${SOURCE_DIR}/${dir}/*.cpp" "${SOURCE_DIR}/${dir}/*.h")
  list(APPEND sources ${found})
endforeach()
list(LENGTH sources count)
execute_process(COMMAND ${CLANG_FORMAT} --dry-run --Werror ${sources} RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "files not formatted (run: clang-format -i FILE):\n${err}")
endif()
message(STATUS "${count} sources formatted")
