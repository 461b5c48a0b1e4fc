// The benchmarks' main: Google Benchmark's, with mtcal's log on stderr so that
// --benchmark_format=json prints one JSON document on stdout, and memory handled as the
// command line handles it (services/memory.h).

#include <benchmark/benchmark.h>

#include "mtcal/services/logging.h"
#include "mtcal/services/memory.h"

int main(int argc, char** argv) {
  mtcal::services::keepFreedMemoryForReuse();  // as the command line does
  mtcal::services::logToStderr("info");
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
