# The front ends (the command line, the library examples) call services only: they include
# no header of acquisition, storage, processing, mocks or drivers and never touch the store.
#   cmake -DDIRS="dir;dir" -P front_ends_call_services.cmake
set(violations "")
foreach(dir ${DIRS})
  file(GLOB_RECURSE sources "${dir}/*.cpp" "${dir}/*.h")
  foreach(source ${sources})
    file(STRINGS "${source}" lines)
    set(number 0)
    foreach(line IN LISTS lines)
      math(EXPR number "${number} + 1")
      if(line MATCHES "#include \"mtcal/(acquisition|storage|processing|mocks|drivers)/"
         OR line MATCHES "\\.store\\(\\)|storage::Store[ &]|addResult\\(")
        string(APPEND violations "\n  ${source}:${number}: ${line}")
      endif()
    endforeach()
  endforeach()
endforeach()
if(violations)
  message(FATAL_ERROR "front ends must call services, not the layers below:${violations}")
endif()
message(STATUS "the front ends call services only")
