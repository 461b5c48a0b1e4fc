# Every build switch of mtcal, prefixed MTCAL_.
option(MTCAL_BUILD_TESTS "Build the GoogleTest suite" ON)
option(MTCAL_BUILD_BENCH "Build the Google Benchmark programs in bench/" ON)
option(MTCAL_BUILD_FUZZ "Build libFuzzer targets (needs clang)" OFF)
option(MTCAL_HARDWARE_TESTS "Register tests that need real instruments attached" OFF)
set(MTCAL_SANITIZE "" CACHE STRING "Sanitizers to build with: address, undefined, thread (comma separated)")

if(MTCAL_SANITIZE)
  add_compile_options(-fsanitize=${MTCAL_SANITIZE} -fno-omit-frame-pointer)
  add_link_options(-fsanitize=${MTCAL_SANITIZE})
endif()
