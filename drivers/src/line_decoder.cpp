#include "mtcal/drivers/line_decoder.h"

namespace mtcal::drivers {

void LineDecoder::feed(std::span<const std::uint8_t> bytes) {
  for (const std::uint8_t b : bytes) {
    if (b == '\n') {
      if (!partial_.empty() && partial_.back() == '\r') partial_.pop_back();
      if (!discarding_) lines_.push_back(std::move(partial_));
      partial_.clear();
      discarding_ = false;
    } else if (!discarding_) {
      partial_.push_back(static_cast<char>(b));
      if (partial_.size() > max_line_bytes_) {
        partial_.clear();
        discarding_ = true;
        ++overlong_;
      }
    }
  }
}

std::optional<std::string> LineDecoder::next() {
  if (head_ == lines_.size()) {
    lines_.clear();
    head_ = 0;
    return std::nullopt;
  }
  return std::move(lines_[head_++]);
}

}  // namespace mtcal::drivers
