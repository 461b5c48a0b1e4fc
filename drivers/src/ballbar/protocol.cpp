#include "mtcal/drivers/ballbar/protocol.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdio>

#include "../byte_order.h"
#include "mtcal/error.h"

namespace mtcal::drivers::ballbar {
namespace {

using byte_order::Reader;
using byte_order::Writer;

const char* reportName(ReportId id) {
  switch (id) {
    case ReportId::kSamples:
      return "SAMPLES";
    case ReportId::kIdentify:
      return "IDENTIFY";
    case ReportId::kZero:
      return "ZERO";
    case ReportId::kRate:
      return "RATE";
    case ReportId::kStream:
      return "STREAM";
    case ReportId::kStatus:
      return "STATUS";
  }
  return "unknown";
}

// Checks the ID and length of a report and returns a reader positioned after the ID.
Reader open(std::span<const std::uint8_t> report, ReportId id, std::size_t size) {
  const std::string name = reportName(id);
  if (report.empty()) throw ProtocolError(name + " report: empty");
  if (report[0] != static_cast<std::uint8_t>(id)) {
    throw ProtocolError(
        fmt::format("{} report: ID 0x{:02x}, expected 0x{:02x}", name, report[0], static_cast<unsigned>(id)));
  }
  if (report.size() != size)
    throw ProtocolError(fmt::format("{} report: {} bytes, expected {}", name, report.size(), size));
  return Reader(report.subspan(1), reportName(id));
}

Writer start(ReportId id) {
  Writer w;
  w.put(static_cast<std::uint8_t>(id));
  return w;
}

std::int16_t centiKelvin(double temperature_c) { return static_cast<std::int16_t>(std::lround(temperature_c * 100.0)); }

std::uint32_t tenthsOfUm(double length_mm, const char* what) {
  const double counts = std::round(length_mm * 1e4);
  if (!(counts > 0.0 && counts <= 4294967295.0)) {
    throw InputError(fmt::format("{} {} mm is out of range (0, 429496 mm]", what, length_mm));
  }
  return static_cast<std::uint32_t>(counts);
}

}  // namespace

const char* resultName(Result result) {
  switch (result) {
    case Result::kOk:
      return "accepted";
    case Result::kBadValue:
      return "value out of range";
    case Result::kBusy:
      return "not allowed while streaming";
    case Result::kUnknownReport:
      return "unknown report";
  }
  return "unknown result";
}

std::vector<std::uint8_t> encodeZero(double reference_length_mm) {
  return start(ReportId::kZero)
      .put(tenthsOfUm(reference_length_mm, "reference length"))
      .padTo(kFeatureReportSize)
      .bytes();
}

std::vector<std::uint8_t> encodeRate(std::uint32_t rate_hz) {
  return start(ReportId::kRate)
      .put(static_cast<std::uint16_t>(std::min<std::uint32_t>(rate_hz, 65535)))
      .padTo(kFeatureReportSize)
      .bytes();
}

std::vector<std::uint8_t> encodeStream(bool on) {
  return start(ReportId::kStream).put(static_cast<std::uint8_t>(on ? 1 : 0)).padTo(kFeatureReportSize).bytes();
}

std::vector<std::uint8_t> featureBuffer(ReportId id) { return start(id).padTo(kFeatureReportSize).bytes(); }

std::vector<std::uint8_t> encodeSamples(const SampleBlock& block) {
  if (block.deviation_um.empty() || block.deviation_um.size() > kMaxSamplesPerReport) {
    throw InputError(
        fmt::format("a sample report holds 1..{} samples, not {}", kMaxSamplesPerReport, block.deviation_um.size()));
  }
  Writer w = start(ReportId::kSamples);
  w.put(block.first_seq).put(block.device_time_us).put(block.period_us);
  w.put(static_cast<std::uint8_t>(block.deviation_um.size())).put(block.flags);
  w.put(centiKelvin(block.temperature_c)).put(block.battery_pct);
  for (const auto& d : block.deviation_um) {
    std::int32_t counts = kOverRangeCount;
    if (d && std::abs(*d / kResolutionUm) < 2.0e9) counts = static_cast<std::int32_t>(std::lround(*d / kResolutionUm));
    w.put(counts);
  }
  return w.padTo(kInputReportSize).bytes();
}

std::vector<std::uint8_t> encodeIdentity(const Identity& id) {
  unsigned major = 0, minor = 0, patch = 0;
  std::sscanf(id.firmware.c_str(), "%u.%u.%u", &major, &minor, &patch);  // NOLINT(cert-err34-c): absent parts stay 0
  Writer w = start(ReportId::kIdentify);
  w.put(id.protocol_version)
      .put(static_cast<std::uint8_t>(major))
      .put(static_cast<std::uint8_t>(minor))
      .put(static_cast<std::uint8_t>(patch));
  w.putFixed(id.serial, 8).putFixed(id.model, 8).put(id.nominal_length_mm).put(id.range_um);
  return w.padTo(kFeatureReportSize).bytes();
}

std::vector<std::uint8_t> encodeStatus(const Status& s) {
  Writer w = start(ReportId::kStatus);
  w.put(static_cast<std::uint8_t>(s.last_command)).put(static_cast<std::uint8_t>(s.result)).put(s.flags).put(s.rate_hz);
  w.put(centiKelvin(s.temperature_c)).put(s.battery_pct).put(s.dropped_samples);
  w.put(s.reference_length_mm > 0.0 ? tenthsOfUm(s.reference_length_mm, "reference length") : std::uint32_t{0});
  return w.padTo(kFeatureReportSize).bytes();
}

SampleBlock parseSamples(std::span<const std::uint8_t> report) {
  Reader r = open(report, ReportId::kSamples, kInputReportSize);
  SampleBlock b;
  b.first_seq = r.get<std::uint32_t>();
  b.device_time_us = r.get<std::uint32_t>();
  b.period_us = r.get<std::uint16_t>();
  const auto count = r.get<std::uint8_t>();
  b.flags = r.get<std::uint8_t>();
  b.temperature_c = r.get<std::int16_t>() / 100.0;
  b.battery_pct = r.get<std::uint8_t>();
  if (count == 0 || count > kMaxSamplesPerReport) {
    throw ProtocolError(fmt::format("SAMPLES report: count {} is not 1..{}", count, kMaxSamplesPerReport));
  }
  if (b.period_us == 0) throw ProtocolError("SAMPLES report: sample period 0 us");
  if (b.battery_pct > 100) throw ProtocolError(fmt::format("SAMPLES report: battery {} % is over 100", b.battery_pct));
  for (int i = 0; i < count; ++i) {
    const auto counts = r.get<std::int32_t>();
    b.deviation_um.push_back(counts == kOverRangeCount ? std::nullopt : std::optional<double>(counts * kResolutionUm));
  }
  return b;
}

Identity parseIdentity(std::span<const std::uint8_t> report) {
  Reader r = open(report, ReportId::kIdentify, kFeatureReportSize);
  Identity id;
  id.protocol_version = r.get<std::uint8_t>();
  const unsigned major = r.get<std::uint8_t>(), minor = r.get<std::uint8_t>(), patch = r.get<std::uint8_t>();
  id.firmware = fmt::format("{}.{}.{}", major, minor, patch);
  id.serial = r.getFixed(8);
  id.model = r.getFixed(8);
  id.nominal_length_mm = r.get<std::uint16_t>();
  id.range_um = r.get<std::uint16_t>();
  if (id.protocol_version != kProtocolVersion) {
    throw ProtocolError(fmt::format("IDENTIFY report: protocol version {}, this driver speaks {}", id.protocol_version,
                                    kProtocolVersion));
  }
  return id;
}

Status parseStatus(std::span<const std::uint8_t> report) {
  Reader r = open(report, ReportId::kStatus, kFeatureReportSize);
  Status s;
  s.last_command = static_cast<ReportId>(r.get<std::uint8_t>());
  const auto result = r.get<std::uint8_t>();
  if (result > static_cast<std::uint8_t>(Result::kUnknownReport)) {
    throw ProtocolError(fmt::format("STATUS report: result code {} is unknown", result));
  }
  s.result = static_cast<Result>(result);
  s.flags = r.get<std::uint8_t>();
  s.rate_hz = r.get<std::uint16_t>();
  s.temperature_c = r.get<std::int16_t>() / 100.0;
  s.battery_pct = r.get<std::uint8_t>();
  s.dropped_samples = r.get<std::uint32_t>();
  s.reference_length_mm = r.get<std::uint32_t>() / 1e4;
  return s;
}

double parseZero(std::span<const std::uint8_t> report) {
  return open(report, ReportId::kZero, kFeatureReportSize).get<std::uint32_t>() / 1e4;
}

std::uint32_t parseRate(std::span<const std::uint8_t> report) {
  return open(report, ReportId::kRate, kFeatureReportSize).get<std::uint16_t>();
}

bool parseStream(std::span<const std::uint8_t> report) {
  const auto on = open(report, ReportId::kStream, kFeatureReportSize).get<std::uint8_t>();
  if (on > 1) throw ProtocolError(fmt::format("STREAM report: value {} is not 0 or 1", on));
  return on == 1;
}

}  // namespace mtcal::drivers::ballbar
