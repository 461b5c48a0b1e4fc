// Fuzz target of the ballbar's HID report codec (docs/protocols/ballbar.md): any bytes given
// as a report to every report parser, the host's and the device's, must parse or throw
// ProtocolError.

#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz_support.h"
#include "mtcal/drivers/ballbar/protocol.h"
#include "mtcal/error.h"

namespace bb = mtcal::drivers::ballbar;
using mtcal::ProtocolError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> report(data, size);
  refused<ProtocolError>([&] { bb::parseSamples(report); });
  refused<ProtocolError>([&] { bb::parseIdentity(report); });
  refused<ProtocolError>([&] { bb::parseStatus(report); });
  refused<ProtocolError>([&] { bb::parseZero(report); });
  refused<ProtocolError>([&] { bb::parseRate(report); });
  refused<ProtocolError>([&] { bb::parseStream(report); });
  return 0;
}
