#include "mtcal/mocks/ballbar_emulator.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "mtcal/error.h"
#include "mtcal/mocks/random.h"

namespace mtcal::mocks {
namespace {
namespace bb = drivers::ballbar;
constexpr std::uint64_t kBallbarNoiseStream = 400;
}  // namespace

BallbarEmulator::BallbarEmulator(VirtualMachine& machine, BallbarEmulatorConfig config)
    : machine_(machine), config_(std::move(config)), reference_mm_(config_.nominal_length_mm) {}

void BallbarEmulator::fitLength(int nominal_length_mm) {
  std::lock_guard lock(mutex_);
  if (nominal_length_mm <= 0) throw InputError("ballbar: nominal length must be > 0 mm");
  config_.nominal_length_mm = nominal_length_mm;
  if (!zeroed_) reference_mm_ = nominal_length_mm;
}

void BallbarEmulator::placeInCalibrator() {
  std::lock_guard lock(mutex_);
  mounted_ = false;
}

void BallbarEmulator::mountOnMachine() {
  const Eigen::Vector3d centre = machine_.actualPointMm(config_.tool_ball_offset_mm, machine_.clock().nowS());
  std::lock_guard lock(mutex_);
  centre_mm_ = centre;
  mounted_ = true;
}

double BallbarEmulator::lengthMm(double t_s) const {
  if (!mounted_) return config_.nominal_length_mm + config_.calibrator_error_um / 1000.0;
  // The table ball is where the tool ball was at the centre; the bar's length is the
  // nominal radius plus what the machine makes of it.
  return (machine_.actualPointMm(config_.tool_ball_offset_mm, t_s) - centre_mm_).norm();
}

double BallbarEmulator::trueLengthMm(double t_s) const {
  std::lock_guard lock(mutex_);
  return lengthMm(t_s);
}

int BallbarEmulator::samplesPerReport() const {
  return static_cast<int>(std::clamp<std::uint32_t>(rate_hz_ / 100, 1, bb::kMaxSamplesPerReport));
}

bb::Status BallbarEmulator::status() const {
  bb::Status s;
  s.last_command = last_command_;
  s.result = last_result_;
  s.flags = static_cast<std::uint8_t>((streaming_ ? bb::kStreaming : 0) | (zeroed_ ? 0 : bb::kNotZeroed) |
                                      (config_.battery_pct < 15 ? bb::kBatteryLow : 0));
  s.rate_hz = static_cast<std::uint16_t>(rate_hz_);
  s.temperature_c = config_.temperature_c;
  s.battery_pct = static_cast<std::uint8_t>(config_.battery_pct);
  s.dropped_samples = dropped_;
  s.reference_length_mm = zeroed_ ? reference_mm_ : 0.0;
  return s;
}

void BallbarEmulator::setFeature(std::span<const std::uint8_t> report) {
  std::lock_guard lock(mutex_);
  if (faults_.unplugged) throw TransportError("ballbar unplugged");
  if (report.empty()) throw ProtocolError("empty feature report");
  const auto id = static_cast<bb::ReportId>(report[0]);
  last_command_ = id;
  last_result_ = bb::Result::kOk;
  switch (id) {
    case bb::ReportId::kZero: {
      const double reference = bb::parseZero(report);
      if (streaming_) {
        last_result_ = bb::Result::kBusy;
      } else if (!(reference > 0.0)) {
        last_result_ = bb::Result::kBadValue;
      } else {
        // The current length (noise-free: the device averages while zeroing) reads `reference`.
        reference_mm_ = reference;
        zero_offset_mm_ = reference - lengthMm(machine_.clock().nowS());
        zeroed_ = true;
      }
      break;
    }
    case bb::ReportId::kRate: {
      const std::uint32_t rate = bb::parseRate(report);
      if (streaming_) {
        last_result_ = bb::Result::kBusy;
      } else if (rate < 1 || rate > bb::kMaxRateHz) {
        last_result_ = bb::Result::kBadValue;
      } else {
        rate_hz_ = rate;
      }
      break;
    }
    case bb::ReportId::kStream: {
      const bool on = bb::parseStream(report);
      if (on && !streaming_) {
        next_k_ = static_cast<std::uint64_t>(std::ceil(machine_.clock().nowS() * rate_hz_));
        overflowed_ = false;
      }
      if (!on) fifo_.clear();
      streaming_ = on;
      break;
    }
    default:
      last_result_ = bb::Result::kUnknownReport;
      throw ProtocolError("feature report 0x" + std::to_string(report[0]) + " cannot be set");
  }
  cv_.notify_all();
}

std::size_t BallbarEmulator::getFeature(std::span<std::uint8_t> buffer) {
  std::lock_guard lock(mutex_);
  if (faults_.unplugged) throw TransportError("ballbar unplugged");
  if (buffer.empty()) throw ProtocolError("empty feature buffer");
  std::vector<std::uint8_t> report;
  switch (static_cast<bb::ReportId>(buffer[0])) {
    case bb::ReportId::kIdentify:
      report = bb::encodeIdentity({bb::kProtocolVersion, config_.firmware, config_.serial, config_.model,
                                   static_cast<std::uint16_t>(config_.nominal_length_mm),
                                   static_cast<std::uint16_t>(config_.range_um)});
      break;
    case bb::ReportId::kStatus:
      report = bb::encodeStatus(status());
      break;
    default:
      throw ProtocolError("feature report 0x" + std::to_string(buffer[0]) + " cannot be read");
  }
  const std::size_t n = std::min(buffer.size(), report.size());
  std::memcpy(buffer.data(), report.data(), n);
  return n;
}

void BallbarEmulator::produce(double now_s) {
  if (!streaming_) return;
  const int full_report = samplesPerReport();
  const double period_s = 1.0 / rate_hz_;
  for (;;) {
    // Samples time-stamped up to now, sent in reports of `full_report`; when a hold keeps the
    // world from completing a report, the samples due so far go in a shorter one (the count
    // byte says how many), so a host that waits for a time gets every sample up to it.
    const auto due =
        static_cast<std::int64_t>(std::floor(now_s * rate_hz_ + 1e-6)) + 1 - static_cast<std::int64_t>(next_k_);
    if (due <= 0) return;
    const double full_due_s = static_cast<double>(next_k_ + static_cast<std::uint64_t>(full_report) - 1) * period_s;
    if (due < full_report && !machine_.clock().heldBelow(full_due_s)) return;
    const int per_report = static_cast<int>(std::min<std::int64_t>(due, full_report));
    // In lock step the world waits for the host: a report the full FIFO cannot take now is
    // made later (the same values, keyed to their times) instead of pushing out the oldest.
    if (machine_.clock().lockStep() && fifo_.size() >= config_.fifo_reports) return;
    bb::SampleBlock block;
    block.first_seq = next_seq_;
    const double t0 = static_cast<double>(next_k_) * period_s;
    block.device_time_us = static_cast<std::uint32_t>(static_cast<std::uint64_t>(std::llround(t0 * 1e6)));
    block.period_us = static_cast<std::uint16_t>(std::lround(period_s * 1e6));
    block.temperature_c = config_.temperature_c;
    block.battery_pct = static_cast<std::uint8_t>(config_.battery_pct);
    block.flags = static_cast<std::uint8_t>(bb::kStreaming | (zeroed_ ? 0 : bb::kNotZeroed) |
                                            (overflowed_ ? bb::kFifoOverflow : 0));
    for (int i = 0; i < per_report; ++i) {
      const std::uint64_t k = next_k_ + static_cast<std::uint64_t>(i);
      const double t = static_cast<double>(k) * period_s;
      // Noise keyed to the machine's last move (a contour) and the sample's place after its
      // end, so a seed gives the same readings along a path whatever the wall clock did.
      const auto [epoch, rest_s] = machine_.moveEpoch(t);
      const auto after_rest =
          static_cast<std::uint64_t>(static_cast<std::int64_t>(k) - std::llround(rest_s * rate_hz_));
      const double deviation_um =
          (lengthMm(t) + zero_offset_mm_ - reference_mm_) * 1000.0 +
          config_.noise_um * normalFromKey(machine_.config().seed, kBallbarNoiseStream + (epoch << 8), after_rest);
      if (std::abs(deviation_um) > config_.range_um) {
        block.flags |= bb::kOverRange;
        block.deviation_um.emplace_back(std::nullopt);
      } else {
        block.deviation_um.emplace_back(deviation_um);
      }
    }
    next_k_ += static_cast<std::uint64_t>(per_report);
    next_seq_ += static_cast<std::uint32_t>(per_report);
    if (faults_.drop_next_reports > 0) {
      --faults_.drop_next_reports;
      continue;
    }
    auto report = bb::encodeSamples(block);
    if (faults_.garble_next_reports > 0) {
      --faults_.garble_next_reports;
      report[11] = 0xEE;  // the count byte
    }
    fifo_.push_back(std::move(report));
    while (fifo_.size() > config_.fifo_reports) {
      fifo_.pop_front();
      dropped_ += static_cast<std::uint32_t>(per_report);
      overflowed_ = true;
    }
  }
}

std::size_t BallbarEmulator::readInput(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout) {
  if (!waitInput(timeout)) return 0;
  std::lock_guard lock(mutex_);
  if (fifo_.empty()) return 0;
  const auto& report = fifo_.front();
  const std::size_t n = std::min(buffer.size(), report.size());
  std::memcpy(buffer.data(), report.data(), n);
  fifo_.pop_front();
  return n;
}

bool BallbarEmulator::waitInput(std::chrono::nanoseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::unique_lock lock(mutex_);
  for (;;) {
    if (faults_.unplugged) throw TransportError("ballbar unplugged");
    produce(machine_.clock().nowS());
    if (!fifo_.empty()) return true;
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) return false;
    // Wake when the next report is due (or a command changes things).
    auto wake = deadline;
    if (streaming_) {
      const double due_s = static_cast<double>(next_k_ + static_cast<std::uint64_t>(samplesPerReport()) - 1) / rate_hz_;
      wake = std::min(wake, machine_.clock().wakeFor(due_s) + std::chrono::microseconds(50));
    }
    cv_.wait_until(lock, wake);
  }
}

void BallbarEmulator::updateFaults(const std::function<void(BallbarFaults&)>& change) {
  std::lock_guard lock(mutex_);
  change(faults_);
  cv_.notify_all();
}

std::size_t EmulatorHidTransport::read(std::span<std::uint8_t> buffer, drivers::milliseconds timeout) {
  const std::size_t n = device_->readInput(buffer, timeout);
  if (n == 0) throw TimeoutError("emulated ballbar: no input report within " + std::to_string(timeout.count()) + " ms");
  return n;
}

void EmulatorHidTransport::write(std::span<const std::uint8_t>, drivers::milliseconds) {
  throw TransportError("emulated ballbar: the device has no output reports");
}

void EmulatorHidTransport::setFeature(std::span<const std::uint8_t> report) {
  try {
    device_->setFeature(report);
  } catch (const ProtocolError& e) {
    throw TransportError(std::string("emulated ballbar: feature report refused: ") + e.what());
  }
}

std::size_t EmulatorHidTransport::getFeature(std::span<std::uint8_t> buffer) {
  try {
    return device_->getFeature(buffer);
  } catch (const ProtocolError& e) {
    throw TransportError(std::string("emulated ballbar: feature report not read: ") + e.what());
  }
}

}  // namespace mtcal::mocks
