#pragma once
// Telescoping ballbar over USB HID (docs/protocols/ballbar.md): the report layouts, shared by
// the host driver and the device emulator in mocks/. Every multi-byte field is little-endian;
// byte 0 of every report is its report ID.
//
// Input report 0x01 (64 bytes): a block of up to 12 length deviations with the sequence
// number of the first, the device time, the sample period, flags, temperature and battery.
// Feature reports (32 bytes): 0x10 identify (get), 0x11 zero against the calibrator's
// reference length (set), 0x12 rate (set), 0x13 stream start/stop (set), 0x14 status (get),
// which also tells whether the last set was accepted.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace mtcal::drivers::ballbar {

inline constexpr std::uint16_t kUsbVendorId = 0x1209;  ///< pid.codes test VID
inline constexpr std::uint16_t kUsbProductId = 0xc418;
inline constexpr std::uint8_t kProtocolVersion = 1;
inline constexpr std::size_t kInputReportSize = 64;
inline constexpr std::size_t kFeatureReportSize = 32;
inline constexpr std::size_t kSampleHeaderSize = 16;
inline constexpr std::size_t kMaxSamplesPerReport = (kInputReportSize - kSampleHeaderSize) / 4;  // 12
inline constexpr std::uint32_t kMaxRateHz = 1000;
inline constexpr double kResolutionUm = 0.1;                ///< one count of a deviation
inline constexpr std::int32_t kOverRangeCount = INT32_MIN;  ///< a sample outside the transducer range

enum class ReportId : std::uint8_t {
  kSamples = 0x01,
  kIdentify = 0x10,
  kZero = 0x11,
  kRate = 0x12,
  kStream = 0x13,
  kStatus = 0x14,
};

/// Flags of sample and status reports.
enum Flags : std::uint8_t {
  kStreaming = 0x01,
  kOverRange = 0x02,  ///< a sample of the block is over range
  kBatteryLow = 0x04,
  kFifoOverflow = 0x08,  ///< the device dropped samples (the sequence numbers jump)
  kNotZeroed = 0x10,     ///< no zero since power-up: deviations are relative to the factory length
};

/// Result of the last set feature, as the status report gives it.
enum class Result : std::uint8_t { kOk = 0, kBadValue = 1, kBusy = 2, kUnknownReport = 3 };
const char* resultName(Result result);

struct SampleBlock {
  std::uint32_t first_seq = 0;
  std::uint32_t device_time_us = 0;  ///< of the first sample (wraps after 71 min)
  std::uint16_t period_us = 1000;
  std::uint8_t flags = 0;
  double temperature_c = 20.0;  ///< 0.01 K resolution
  std::uint8_t battery_pct = 100;
  /// Length deviations, um (0.1 um resolution); nullopt: over range.
  std::vector<std::optional<double>> deviation_um;
};

struct Identity {
  std::uint8_t protocol_version = kProtocolVersion;
  std::string firmware = "1.0.0";  ///< major.minor.patch
  std::string serial;              ///< up to 8 characters
  std::string model;               ///< up to 8 characters
  std::uint16_t nominal_length_mm = 100;
  std::uint16_t range_um = 1000;  ///< measuring range +-
};

struct Status {
  ReportId last_command = ReportId::kStatus;
  Result result = Result::kOk;
  std::uint8_t flags = 0;
  std::uint16_t rate_hz = 0;
  double temperature_c = 20.0;
  std::uint8_t battery_pct = 100;
  std::uint32_t dropped_samples = 0;  ///< by the device since power-up
  double reference_length_mm = 0.0;   ///< of the last zero (0: never zeroed)
};

// Host -> device (set feature reports).
std::vector<std::uint8_t> encodeZero(double reference_length_mm);
std::vector<std::uint8_t> encodeRate(std::uint32_t rate_hz);
std::vector<std::uint8_t> encodeStream(bool on);
/// An empty get-feature buffer for this report (ID set).
std::vector<std::uint8_t> featureBuffer(ReportId id);

// Device -> host.
std::vector<std::uint8_t> encodeSamples(const SampleBlock& block);
std::vector<std::uint8_t> encodeIdentity(const Identity& identity);
std::vector<std::uint8_t> encodeStatus(const Status& status);

/// @throws ProtocolError naming the report and what is wrong (ID, length, count, values).
SampleBlock parseSamples(std::span<const std::uint8_t> report);
Identity parseIdentity(std::span<const std::uint8_t> report);
Status parseStatus(std::span<const std::uint8_t> report);
/// Device side: the values of set features. @throws ProtocolError
double parseZero(std::span<const std::uint8_t> report);
std::uint32_t parseRate(std::span<const std::uint8_t> report);
bool parseStream(std::span<const std::uint8_t> report);

}  // namespace mtcal::drivers::ballbar
