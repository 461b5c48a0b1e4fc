// Fuzz target of the laser tracker's line codec (docs/protocols/tracker.md): any byte stream
// split into lines as the driver splits it; every line parsed as a request (the emulator's
// side) and as a reply or event, and every payload parser given the fields: each must parse
// or throw ProtocolError.

#include <cstddef>
#include <cstdint>
#include <span>
#include <variant>

#include "fuzz_support.h"
#include "mtcal/drivers/line_decoder.h"
#include "mtcal/drivers/tracker/protocol.h"
#include "mtcal/error.h"

namespace tp = mtcal::drivers::tracker;
using mtcal::ProtocolError;
using mtcal::fuzz::refused;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  mtcal::drivers::LineDecoder decoder(tp::kMaxLineBytes);
  // Fed in two pieces to exercise reassembly at a data-dependent split.
  const std::size_t split = size > 0 ? data[0] % (size + 1) : 0;
  decoder.feed(std::span(data, split));
  decoder.feed(std::span(data + split, size - split));
  while (const auto line = decoder.next()) {
    refused<ProtocolError>([&] { tp::parseRequest(*line); });
    refused<ProtocolError>([&] {
      const auto message = tp::parseMessage(*line);
      if (const auto* reply = std::get_if<tp::Reply>(&message)) {
        if (reply->kind == tp::Reply::Kind::kError) {
          tp::errorName(reply->error_code());
          reply->error_text();
        }
        refused<ProtocolError>([&] { tp::parseHello(reply->fields); });
        refused<ProtocolError>([&] { tp::parsePoint(reply->fields); });
        refused<ProtocolError>([&] { tp::reflectorRadiusMm(tp::parseStatus(reply->fields).reflector); });
      } else {
        tp::parseStreamPoint(std::get<tp::Event>(message));
      }
    });
  }
  return 0;
}
