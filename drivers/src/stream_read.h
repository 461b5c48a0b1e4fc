#pragma once
// One read of a driver's reader loop, shared by the instrument drivers: what arrived within
// the read timeout, or 0 when nothing did; nothing since `last_data` for longer than `stall`
// is an error. The caller decides what counts as data (a frame, a line, a report) and keeps
// `last_data`.

#include <fmt/format.h>

#include <chrono>
#include <span>
#include <string>

#include "mtcal/drivers/transport.h"
#include "mtcal/error.h"

namespace mtcal::drivers {

/// @throws TimeoutError "URI: stream stalled: nothing for N ms"; whatever the transport throws
inline std::size_t readOrStall(Transport& transport, std::span<std::uint8_t> buffer, milliseconds read_timeout,
                               milliseconds stall, std::chrono::steady_clock::time_point last_data,
                               const std::string& uri) {
  try {
    return transport.read(buffer, read_timeout);
  } catch (const TimeoutError&) {
    if (std::chrono::steady_clock::now() - last_data > stall) {
      throw TimeoutError(fmt::format("{}: stream stalled: nothing for {} ms", uri, stall.count()));
    }
    return 0;
  }
}

}  // namespace mtcal::drivers
