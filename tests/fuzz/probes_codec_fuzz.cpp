// Fuzz target of the probe interface box's line codec (docs/protocols/probes.md): any byte
// stream split into lines as the driver splits it, and every line given to every reply parser
// (with the channel count of the last valid CH reply, as the driver does) and to the device
// side's command parser, must parse or throw ProtocolError (DeviceError for an ERR reply).

#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz_support.h"
#include "mtcal/drivers/line_decoder.h"
#include "mtcal/drivers/probes/protocol.h"
#include "mtcal/error.h"

namespace pb = mtcal::drivers::probes;
using mtcal::DeviceError;
using mtcal::ProtocolError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  mtcal::drivers::LineDecoder decoder(pb::kMaxLineBytes);
  // Fed in two pieces to exercise reassembly at a data-dependent split.
  const std::size_t split = size > 0 ? data[0] % (size + 1) : 0;
  decoder.feed(std::span(data, split));
  decoder.feed(std::span(data + split, size - split));
  int channels = 3;
  while (const auto line = decoder.next()) {
    refused<ProtocolError, DeviceError>([&] { pb::parseIdentity(*line); });
    refused<ProtocolError, DeviceError>([&] { channels = pb::parseChannels(*line).count; });
    refused<ProtocolError, DeviceError>([&] { pb::parseValues(*line, channels); });
    refused<ProtocolError, DeviceError>([&] { pb::parseOk(*line); });
    if (pb::isStreamLine(*line)) refused<ProtocolError>([&] { pb::parseStreamLine(*line, channels); });
    refused<ProtocolError>([&] { pb::parseCommand(*line); });
  }
  return 0;
}
