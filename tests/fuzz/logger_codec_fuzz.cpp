// Fuzz target of the temperature logger's line codec (docs/protocols/logger.md): any byte
// stream split into lines as the driver splits it, and every line given to every reply parser
// (with the channel count of the last valid CH reply, as the driver does) and to the device
// side's command parser, must parse or throw ProtocolError (DeviceError for an ERR reply).

#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz_support.h"
#include "mtcal/drivers/line_decoder.h"
#include "mtcal/drivers/logger/protocol.h"
#include "mtcal/error.h"

namespace lg = mtcal::drivers::logger;
using mtcal::DeviceError;
using mtcal::ProtocolError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  mtcal::drivers::LineDecoder decoder(lg::kMaxLineBytes);
  // Fed in two pieces to exercise reassembly at a data-dependent split.
  const std::size_t split = size > 0 ? data[0] % (size + 1) : 0;
  decoder.feed(std::span(data, split));
  decoder.feed(std::span(data + split, size - split));
  int channels = 8;
  while (const auto line = decoder.next()) {
    refused<ProtocolError, DeviceError>([&] { lg::parseIdentity(*line); });
    refused<ProtocolError, DeviceError>([&] { channels = lg::parseChannels(*line).count; });
    refused<ProtocolError, DeviceError>([&] { lg::parseReading(*line, channels); });
    refused<ProtocolError, DeviceError>([&] { lg::parseOk(*line); });
    if (lg::isRecordLine(*line)) refused<ProtocolError>([&] { lg::parseRecord(*line, channels); });
    refused<ProtocolError>([&] { lg::parseCommand(*line); });
  }
  return 0;
}
