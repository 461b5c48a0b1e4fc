#pragma once
// Little-endian writer and reader of message payloads and reports, shared by the codecs.
// The reader throws ProtocolError naming the message on underrun or trailing bytes.

#include <algorithm>
#include <bit>
#include <cstdint>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

#include "mtcal/error.h"

namespace mtcal::drivers::byte_order {

class Writer {
 public:
  template <typename T>
  Writer& put(T value) {
    static_assert(std::is_integral_v<T>);
    for (std::size_t i = 0; i < sizeof(T); ++i) {
      bytes_.push_back(static_cast<std::uint8_t>(static_cast<std::make_unsigned_t<T>>(value) >> (8 * i)));
    }
    return *this;
  }
  Writer& putDouble(double value) { return put(std::bit_cast<std::uint64_t>(value)); }
  Writer& putString(const std::string& text) {
    const auto n = static_cast<std::uint8_t>(std::min<std::size_t>(text.size(), 255));
    put(n);
    bytes_.insert(bytes_.end(), text.begin(), text.begin() + n);
    return *this;
  }
  /// A text in a fixed field of n bytes, NUL-padded (cut at n).
  Writer& putFixed(const std::string& text, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) bytes_.push_back(i < text.size() ? static_cast<std::uint8_t>(text[i]) : 0);
    return *this;
  }
  /// Pads with zero bytes up to `size` (fixed-size reports).
  Writer& padTo(std::size_t size) {
    if (bytes_.size() < size) bytes_.resize(size, 0);
    return *this;
  }
  std::vector<std::uint8_t>& bytes() { return bytes_; }

 private:
  std::vector<std::uint8_t> bytes_;
};

class Reader {
 public:
  Reader(std::span<const std::uint8_t> data, const char* what) : data_(data), what_(what) {}
  template <typename T>
  T get() {
    need(sizeof(T));
    std::make_unsigned_t<T> value = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i) {
      value |= static_cast<std::make_unsigned_t<T>>(static_cast<std::make_unsigned_t<T>>(data_[pos_ + i]) << (8 * i));
    }
    pos_ += sizeof(T);
    return static_cast<T>(value);
  }
  double getDouble() { return std::bit_cast<double>(get<std::uint64_t>()); }
  std::string getString() {
    auto n = get<std::uint8_t>();
    need(n);
    std::string s(reinterpret_cast<const char*>(data_.data() + pos_), n);
    pos_ += n;
    return s;
  }
  void end() const {
    if (pos_ != data_.size()) {
      throw ProtocolError(std::string(what_) + ": " + std::to_string(data_.size() - pos_) +
                          " unexpected trailing byte(s)");
    }
  }

  /// A NUL-padded text field of n bytes.
  std::string getFixed(std::size_t n) {
    need(n);
    std::string s(reinterpret_cast<const char*>(data_.data() + pos_), n);
    pos_ += n;
    return s.substr(0, s.find('\0'));
  }
  /// Skips n bytes (reserved fields).
  void skip(std::size_t n) {
    need(n);
    pos_ += n;
  }

 private:
  void need(std::size_t n) const {
    if (pos_ + n > data_.size()) {
      throw ProtocolError(std::string(what_) + ": payload of " + std::to_string(data_.size()) +
                          " byte(s) is too short (needs more than " + std::to_string(pos_ + n - 1) + ")");
    }
  }
  std::span<const std::uint8_t> data_;
  std::size_t pos_ = 0;
  const char* what_;
};
}  // namespace mtcal::drivers::byte_order
