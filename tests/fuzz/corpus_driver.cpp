// Runs the fuzz target without libFuzzer: valid frames of every type, then seeded random
// mutations of them (bit flips, truncations, splices), so the suite exercises the target
// on every build. Usage: interferometer_codec_corpus [ITERATIONS]

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "mtcal/drivers/interferometer/protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

namespace ifm = mtcal::drivers::interferometer;

int main(int argc, char** argv) {
  const long iterations = argc > 1 ? std::strtol(argv[1], nullptr, 10) : 10000;
  ifm::DataBlock block{3, 123456789, 20000, {{1, 80, true}, {-2, 0, false}, {1LL << 40, 100, true}}};
  const std::vector<std::vector<std::uint8_t>> corpus = {
      ifm::encodeIdentify(),
      ifm::encodeStartStream(50000),
      ifm::encodeSetOptics(ifm::Optics::kLinear),
      ifm::encodeAck(ifm::MessageType::kStopStream),
      ifm::encodeNak({ifm::MessageType::kStartStream, ifm::NakCode::kBeamLost, "beam"}),
      ifm::encodeIdentity({1, 632.99, "M", "S", "F"}),
      ifm::encodeEnvironment({20.1, 101000.0, 40.0, true, true, false, {20.0, 21.0}}),
      ifm::encodeData(block),
  };
  std::mt19937_64 rng(20261122);
  long runs = 0;
  for (const auto& c : corpus) {
    LLVMFuzzerTestOneInput(c.data(), c.size());
    ++runs;
  }
  for (long i = 0; i < iterations; ++i) {
    std::vector<std::uint8_t> input;
    const int pieces = 1 + static_cast<int>(rng() % 3);
    for (int p = 0; p < pieces; ++p) {
      const auto& c = corpus[rng() % corpus.size()];
      input.insert(input.end(), c.begin(), c.end());
    }
    const int mutations = static_cast<int>(rng() % 6);
    for (int m = 0; m < mutations && !input.empty(); ++m) {
      switch (rng() % 4) {
        case 0:
          input[rng() % input.size()] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
          break;
        case 1:
          input.resize(rng() % input.size());
          break;
        case 2:
          input.insert(input.begin() + static_cast<long>(rng() % input.size()), static_cast<std::uint8_t>(rng()));
          break;
        default:
          input[rng() % input.size()] = static_cast<std::uint8_t>(rng());
          break;
      }
    }
    LLVMFuzzerTestOneInput(input.data(), input.size());
    ++runs;
  }
  std::printf("%ld inputs decoded without a crash\n", runs);
  return 0;
}
