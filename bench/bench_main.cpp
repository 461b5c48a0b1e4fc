// The benchmarks' main: Google Benchmark's, with mtcal's log on stderr so that
// --benchmark_format=json prints one JSON document on stdout.

#include <benchmark/benchmark.h>

#include "mtcal/services/logging.h"

int main(int argc, char** argv) {
  mtcal::services::logToStderr("info");
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
