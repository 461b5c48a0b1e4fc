#pragma once
// Splits a byte stream into lines (CR LF or LF), for the line protocols (probe box, laser
// tracker). A line longer than the limit is dropped up to its end and counted.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace mtcal::drivers {

class LineDecoder {
 public:
  explicit LineDecoder(std::size_t max_line_bytes) : max_line_bytes_(max_line_bytes) {}
  void feed(std::span<const std::uint8_t> bytes);
  std::optional<std::string> next();
  std::uint64_t overlongLines() const { return overlong_; }

 private:
  std::size_t max_line_bytes_;
  std::string partial_;
  std::vector<std::string> lines_;
  std::size_t head_ = 0;
  bool discarding_ = false;
  std::uint64_t overlong_ = 0;
};

}  // namespace mtcal::drivers
