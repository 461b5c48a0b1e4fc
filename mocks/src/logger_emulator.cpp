#include "mtcal/mocks/logger_emulator.h"

#include <cmath>

#include "byte_queue.h"
#include "mtcal/error.h"
#include "mtcal/mocks/random.h"

namespace mtcal::mocks {
namespace lg = drivers::logger;
namespace {
constexpr std::uint64_t kLoggerNoiseStream = 600, kLoggerOffsetStream = 601;
}

LoggerEmulator::LoggerEmulator(VirtualMachine& machine, LoggerEmulatorConfig config)
    : machine_(machine), config_(std::move(config)) {
  if (config_.channels != 8 && config_.channels != 16)
    throw InputError("temperature logger emulator: 8 or 16 channels");
  for (int c = 0; c < config_.channels; ++c) {
    offset_c_.push_back(config_.offset_k *
                        (2.0 * uniformFromKey(mix64(machine_.config().seed ^ (kLoggerOffsetStream << 32) ^ c)) - 1.0));
  }
}

void LoggerEmulator::setTriggerOutput(std::function<void(double t_s)> output) {
  std::lock_guard lock(mutex_);
  trigger_output_ = std::move(output);
}

void LoggerEmulator::updateFaults(const std::function<void(LoggerFaults&)>& change) {
  {
    std::lock_guard lock(mutex_);
    change(faults_);
  }
  cv_.notify_all();
}

double LoggerEmulator::trueReadingC(int channel, double t_s) const {
  const auto i = static_cast<std::size_t>(channel - 1);
  if (const auto* thermal = machine_.thermal())
    return thermal->at(t_s).sensors_c(static_cast<Eigen::Index>(i)) + offset_c_[i];
  return machine_.config().air_temp_c + offset_c_[i];
}

lg::Record LoggerEmulator::convert(double t_s, std::uint64_t key) const {
  lg::Record r;
  r.time_ms = std::llround(t_s * 1000.0);
  Eigen::VectorXd sites;
  if (const auto* thermal = machine_.thermal()) sites = thermal->at(t_s).sensors_c;
  for (int c = 0; c < config_.channels; ++c) {
    const auto i = static_cast<std::size_t>(c);
    const double site = sites.size() > c ? sites(c) : machine_.config().air_temp_c;
    const double noise = config_.noise_k * normalFromKey(machine_.config().seed, kLoggerNoiseStream, key * 32 + i);
    lg::Reading reading{std::round((site + offset_c_[i] + noise) * 100.0) / 100.0, lg::SensorStatus::kOk};
    for (const auto& d : faults_.dropouts) {
      if (d.channel == c + 1 && t_s >= d.from_s && t_s < d.to_s) reading = {0.0, lg::SensorStatus::kOpen};
    }
    r.channels.push_back(reading);
  }
  return r;
}

void LoggerEmulator::execute(const std::string& text) {
  lg::Command c{};
  try {
    c = lg::parseCommand(text);
  } catch (const ProtocolError&) {
    const std::string reply = lg::formatError(1, "unknown or malformed command");
    appendBytes(out_, reply);
    return;
  }
  std::string reply;
  switch (c.kind) {
    case lg::Command::Kind::kIdentify:
      reply = lg::formatIdentity({"MTCAL", config_.model, config_.serial, config_.firmware});
      break;
    case lg::Command::Kind::kChannels:
      reply = lg::formatChannels({config_.channels, 0.01});
      break;
    case lg::Command::Kind::kRead: {
      // The latest of the logger's conversions, made every whole second.
      const double t = std::floor(machine_.clock().nowS());
      reply = lg::formatReading(convert(t, (std::uint64_t{1} << 40) + static_cast<std::uint64_t>(t)));
      break;
    }
    case lg::Command::Kind::kLog:
      logging_ = c.interval_s > 0;
      if (logging_) {
        interval_s_ = c.interval_s;
        next_index_ = 0;
        first_record_s_ = std::ceil(machine_.clock().nowS());
      }
      reply = lg::formatOk();
      break;
  }
  appendBytes(out_, reply);
}

bool LoggerEmulator::logging() const {
  std::lock_guard lock(mutex_);
  return logging_;
}

void LoggerEmulator::receive(std::span<const std::uint8_t> bytes) {
  {
    std::lock_guard lock(mutex_);
    decoder_.feed(bytes);
    while (auto line = decoder_.next()) {
      if (!faults_.silent) execute(*line);
    }
  }
  cv_.notify_all();
}

std::size_t LoggerEmulator::transmit(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::unique_lock lock(mutex_);
  for (;;) {
    if (logging_ && !faults_.silent) {
      for (;;) {
        const double t = first_record_s_ + static_cast<double>(next_index_) * interval_s_;
        if (machine_.clock().nowS() < t) break;
        lg::Record r = convert(t, next_index_);
        r.index = next_index_++;
        const std::string line = lg::formatRecord(r);
        appendBytes(out_, line);
        if (trigger_output_) trigger_output_(t);  // the pulse at the record's time
      }
    }
    if (!out_.empty()) break;
    if (std::chrono::steady_clock::now() >= deadline) return 0;
    auto wake = deadline;
    if (logging_)
      wake = std::min(wake, machine_.clock().wakeFor(first_record_s_ + static_cast<double>(next_index_) * interval_s_));
    cv_.wait_until(lock, wake);
  }
  return takeBytes(out_, buffer);
}

}  // namespace mtcal::mocks
