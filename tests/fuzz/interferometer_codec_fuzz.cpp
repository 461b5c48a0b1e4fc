// Fuzz target of the interferometer codec: any byte stream fed to the frame decoder, and
// every decoded frame given to every payload parser, must either parse or throw
// ProtocolError: no crash, no hang, no other exception, no unbounded buffering.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "mtcal/drivers/interferometer/protocol.h"
#include "mtcal/error.h"

namespace ifm = mtcal::drivers::interferometer;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  ifm::FrameDecoder decoder;
  // Feed in two pieces to exercise reassembly at a data-dependent split.
  const std::size_t split = size > 0 ? data[0] % (size + 1) : 0;
  decoder.feed(std::span(data, split));
  for (int pass = 0; pass < 2; ++pass) {
    while (auto frame = decoder.next()) {
      auto attempt = [&](auto parse) {
        try {
          parse(*frame);
        } catch (const mtcal::ProtocolError&) {
        }
      };
      attempt(ifm::parseAck);
      attempt(ifm::parseNak);
      attempt(ifm::parseIdentity);
      attempt(ifm::parseEnvironment);
      attempt(ifm::parseData);
      attempt(ifm::parseSetOptics);
      attempt(ifm::parseStartStream);
    }
    if (pass == 0) decoder.feed(std::span(data + split, size - split));
  }
  if (decoder.buffered() > ifm::kHeaderSize + ifm::kMaxPayload + ifm::kTrailerSize) std::abort();
  return 0;
}
