#pragma once
// The emulators' transmit queue: bytes waiting for the host.

#include <algorithm>
#include <cstdint>
#include <deque>
#include <span>
#include <string>

namespace mtcal::mocks {

inline void appendBytes(std::deque<std::uint8_t>& queue, const std::string& text) {
  queue.insert(queue.end(), text.begin(), text.end());
}

/// Moves up to buffer.size() bytes from the front of the queue into the buffer. @return how many
inline std::size_t takeBytes(std::deque<std::uint8_t>& queue, std::span<std::uint8_t> buffer) {
  const std::size_t n = std::min(buffer.size(), queue.size());
  std::copy_n(queue.begin(), n, buffer.begin());
  queue.erase(queue.begin(), queue.begin() + static_cast<std::ptrdiff_t>(n));
  return n;
}

}  // namespace mtcal::mocks
