#include "mtcal/mocks/interferometer_emulator.h"

#include <algorithm>
#include <cmath>
#include <thread>

#include "byte_queue.h"
#include "mtcal/error.h"
#include "mtcal/mocks/random.h"
#include "mtcal/processing/air_index.h"

namespace mtcal::mocks {

namespace ifm = drivers::interferometer;

namespace {
constexpr std::uint64_t kReadingStream = 100;
constexpr std::uint64_t kEnvironmentStream = 200;
}  // namespace

InterferometerEmulator::InterferometerEmulator(VirtualMachine& machine, InterferometerEmulatorConfig config)
    : machine_(machine), config_(std::move(config)), axis_(config_.axis), reflector_offset_mm_(config_.beam_offset_mm) {
  const auto& c = machine_.config();
  air_index_ =
      processing::edlenIndex({c.air_temp_c, c.air_pressure_pa, c.humidity_pct, 450.0}, config_.vacuum_wavelength_nm);
  datum_mm_ = machine_.actualPositionMm(axis_, reflector_offset_mm_, machine_.clock().nowS());
}

void InterferometerEmulator::updateFaults(const std::function<void(InterferometerFaults&)>& change) {
  {
    std::lock_guard lock(mutex_);
    change(faults_);
  }
  cv_.notify_all();
}

bool InterferometerEmulator::streaming() const {
  std::lock_guard lock(mutex_);
  return streaming_;
}

void InterferometerEmulator::mount(Axis axis, int component, const ToolOffset& reflector_offset_mm) {
  std::lock_guard lock(mutex_);
  axis_ = axis;
  mounted_component_ = component;
  reflector_offset_mm_ = reflector_offset_mm;
}

std::uint64_t InterferometerEmulator::samplesOverflowed() const {
  std::lock_guard lock(mutex_);
  return samples_overflowed_;
}

void InterferometerEmulator::receive(std::span<const std::uint8_t> bytes) {
  std::unique_lock lock(mutex_);
  if (faults_.disconnected) throw TransportError("emulated interferometer: device disconnected");
  decoder_.feed(bytes);
  while (auto frame = decoder_.next()) {
    if (!faults_.silent) execute(*frame);
  }
  lock.unlock();
  cv_.notify_all();
}

void InterferometerEmulator::queueFrame(std::vector<std::uint8_t> frame) {
  if (faults_.corrupt_next_frames > 0) {
    --faults_.corrupt_next_frames;
    frame[frame.size() / 2] ^= 0x5A;  // CRC catches it
  }
  out_.insert(out_.end(), frame.begin(), frame.end());
}

void InterferometerEmulator::execute(const ifm::Frame& frame) {
  using ifm::MessageType;
  auto nak = [&](ifm::NakCode code, const std::string& text) { queueFrame(ifm::encodeNak({frame.type, code, text})); };
  try {
    switch (frame.type) {
      case MessageType::kIdentify:
        queueFrame(ifm::encodeIdentity(
            {ifm::kProtocolVersion, config_.vacuum_wavelength_nm, config_.model, config_.serial, config_.firmware}));
        return;
      case MessageType::kSetOptics: {
        auto optics = ifm::parseSetOptics(frame);
        if (streaming_) return nak(ifm::NakCode::kBusy, "stop the stream before changing optics");
        const bool angular_mounted = mounted_component_ >= 3;
        const bool straightness_mounted =
            mounted_component_ >= 0 && mounted_component_ < 3 && mounted_component_ != static_cast<int>(axis_);
        if ((optics == ifm::Optics::kAngular && !angular_mounted) ||
            ((optics == ifm::Optics::kStraightnessShort || optics == ifm::Optics::kStraightnessLong) &&
             !straightness_mounted)) {
          return nak(ifm::NakCode::kBadParameter, "these optics are not mounted");
        }
        optics_ = optics;
        queueFrame(ifm::encodeAck(frame.type));
        return;
      }
      case MessageType::kStartStream: {
        const auto rate = ifm::parseStartStream(frame);
        if (streaming_) return nak(ifm::NakCode::kBusy, "already streaming");
        if (rate < 1 || rate > ifm::kMaxRateHz) return nak(ifm::NakCode::kBadParameter, "rate must be 1..50000 Hz");
        if (faults_.nak_start_stream) return nak(ifm::NakCode::kBeamLost, "beam interrupted: check alignment");
        queueFrame(ifm::encodeAck(frame.type));
        rate_hz_ = rate;
        streaming_ = true;
        stream_start_s_ = machine_.clock().nowS();
        stream_first_seq_ = next_seq_;  // sequence numbers keep counting across streams
        return;
      }
      case MessageType::kStopStream:
        streaming_ = false;
        queueFrame(ifm::encodeAck(frame.type));
        return;
      case MessageType::kReadEnvironment: {
        const auto& c = machine_.config();
        const std::uint64_t k = env_reads_++ * 8;
        ifm::Environment env;
        // With a thermal state the air and material sensors read the shop's air and the
        // machine's sites (bed, column base, headstock side) at their temperatures of the moment.
        const auto* thermal = machine_.thermal();
        ThermalState state;
        if (thermal) state = thermal->at(machine_.clock().nowS());
        auto material_c = [&](int i) {
          if (!thermal) return c.material_temp_c;
          static const char* kSites[] = {"bed", "column_base", "headstock_side"};
          const auto& sites = thermal->config().model.sensors;
          for (std::size_t s = 0; s < sites.size(); ++s) {
            if (i < 3 && sites[s].name == kSites[i]) return state.sensors_c(static_cast<Eigen::Index>(s));
          }
          return c.material_temp_c;
        };
        env.air_temp_c = (thermal ? state.ambient_c : c.air_temp_c) +
                         config_.env_noise_temp_k * normalFromKey(c.seed, kEnvironmentStream, k);
        env.air_pressure_pa =
            c.air_pressure_pa + config_.env_noise_pressure_pa * normalFromKey(c.seed, kEnvironmentStream, k + 1);
        env.humidity_pct =
            c.humidity_pct + config_.env_noise_humidity_pct * normalFromKey(c.seed, kEnvironmentStream, k + 2);
        for (int i = 0; i < config_.material_sensors; ++i) {
          env.material_temps_c.push_back(material_c(i) + config_.env_noise_temp_k *
                                                             normalFromKey(c.seed, kEnvironmentStream, k + 3 + i));
        }
        queueFrame(ifm::encodeEnvironment(env));
        return;
      }
      case MessageType::kSetDatum:
        datum_mm_ = machine_.actualPositionMm(axis_, reflector_offset_mm_, machine_.clock().nowS());
        queueFrame(ifm::encodeAck(frame.type));
        return;
      default:
        return nak(ifm::NakCode::kUnknownCommand, "not a host command: " + ifm::messageName(frame.type));
    }
  } catch (const ProtocolError& e) {
    nak(ifm::NakCode::kBadParameter, e.what());
  }
}

double InterferometerEmulator::gridTime(double t_s, double done_s) const {
  const auto offset = static_cast<std::int64_t>(std::floor((t_s - done_s) * rate_hz_ + 1e-6));
  return offset >= 0 ? done_s + static_cast<double>(offset) / rate_hz_ : t_s;
}

double InterferometerEmulator::airIndexAt(double t_s) const {
  const auto* thermal = machine_.thermal();
  if (!thermal) return air_index_;
  const auto& c = machine_.config();
  return processing::edlenIndex({thermal->at(t_s).ambient_c, c.air_pressure_pa, c.humidity_pct, 450.0},
                                config_.vacuum_wavelength_nm);
}

ifm::RawSample InterferometerEmulator::sampleAt(double t_s, const std::optional<double>& settled_mm,
                                                double air_index) const {
  ifm::RawSample s;
  if (faults_.beam_blocked) {
    s.beam_ok = false;
    s.signal_pct = 0;
    return s;
  }
  // Everything is evaluated on a sample grid anchored to the last move: a capture window that
  // starts a fixed time after a move then sees the same machine state and the same noise,
  // whatever the wall-clock timing of the stream was. This is what makes a seeded campaign
  // identical from run to run.
  const auto [move, done_s] = machine_.moveEpoch(t_s);
  const auto offset = static_cast<std::int64_t>(std::floor((t_s - done_s) * rate_hz_ + 1e-6));
  const std::uint64_t key = (move << 32) ^ static_cast<std::uint64_t>(offset);
  const double noise = normalFromKey(machine_.config().seed, kReadingStream, key);
  if (optics_ == ifm::Optics::kLinear) {
    const double true_mm =
        settled_mm ? *settled_mm
                   : machine_.actualPositionMm(axis_, reflector_offset_mm_, gridTime(t_s, done_s)) - datum_mm_;
    const double raw_mm = air_index * true_mm + config_.noise_um * noise / 1000.0;
    s.value = std::llround(raw_mm * 1e9);  // pm
  } else {
    const double t_grid = gridTime(t_s, done_s);
    const double v = mounted_component_ < 3 ? machine_.pointErrorUm(reflector_offset_mm_, t_grid)(mounted_component_)
                                            : machine_.rotationErrorUrad(t_grid)(mounted_component_ - 3);
    s.value = optics_ == ifm::Optics::kAngular ? std::llround((v + config_.angular_noise_urad * noise) * 1e3)  // nrad
                                               : std::llround((v + config_.noise_um * noise) * 1e6);           // pm
  }
  s.signal_pct = config_.signal_pct;
  s.beam_ok = true;
  return s;
}

void InterferometerEmulator::generateDue() {
  if (!streaming_ || faults_.silent) return;
  const double period_s = 1.0 / rate_hz_;
  std::size_t due;
  if (config_.paced) {
    // Every sample time-stamped up to now (within a millionth of a period).
    const double elapsed = machine_.clock().nowS() - stream_start_s_;
    const auto total_due = static_cast<std::uint64_t>(std::max(0.0, std::floor(elapsed * rate_hz_ + 1e-6) + 1.0));
    const std::uint64_t sent = next_seq_ - stream_first_seq_;
    due = total_due > sent ? static_cast<std::size_t>(total_due - sent) : 0;
  } else {
    due = ifm::kMaxSamplesPerFrame;
  }
  if (faults_.disconnect_at_seq)
    due = std::min<std::size_t>(due, *faults_.disconnect_at_seq - std::min(next_seq_, *faults_.disconnect_at_seq));
  while (due > 0) {
    // In lock step the world waits for the host: samples the full buffer cannot take now are
    // made later, with their own time stamps (the same values), instead of being lost.
    if (machine_.clock().lockStep() && out_.size() >= config_.device_buffer_bytes) return;
    const std::size_t n = std::min(due, ifm::kMaxSamplesPerFrame);
    const std::uint32_t first_seq = next_seq_;
    next_seq_ += static_cast<std::uint32_t>(n);
    due -= n;
    // Frames that are lost anyway (injected fault, or the FIFO is full because the host does
    // not read) are not computed: catching up on a backlog must not block the link.
    if (faults_.drop_next_data_frames > 0) {
      --faults_.drop_next_data_frames;
      continue;
    }
    if (out_.size() >= config_.device_buffer_bytes) {
      samples_overflowed_ += n;
      continue;
    }
    ifm::DataBlock block;
    block.first_seq = first_seq;
    block.period_ns = static_cast<std::uint32_t>(std::llround(period_s * 1e9));
    const double t0 = stream_start_s_ + static_cast<double>(first_seq - stream_first_seq_) * period_s;
    block.first_time_ns = static_cast<std::uint64_t>(std::llround(t0 * 1e9));
    block.samples.reserve(n);
    // A block that lies wholly after the axis settled sees one constant position: evaluate
    // the machine once for it instead of once per sample (exactly the same values).
    std::optional<double> settled_mm;
    const double t_last = t0 + static_cast<double>(n - 1) * period_s;
    const auto first_epoch = machine_.moveEpoch(t0);
    // (Before the first move the machine has stood still since the world began.)
    if (first_epoch == machine_.moveEpoch(t_last) &&
        (first_epoch.first == 0 || t0 >= first_epoch.second + machine_.settledAfterS())) {
      settled_mm = machine_.actualPositionMm(axis_, reflector_offset_mm_, t0) - datum_mm_;
    }
    const double air_index = airIndexAt(t0);  // the air changes over minutes, not within a block
    for (std::size_t i = 0; i < n; ++i)
      block.samples.push_back(sampleAt(t0 + static_cast<double>(i) * period_s, settled_mm, air_index));
    queueFrame(ifm::encodeData(block));
  }
}

std::size_t InterferometerEmulator::transmit(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::unique_lock lock(mutex_);
  for (;;) {
    if (faults_.disconnect_at_seq && next_seq_ >= *faults_.disconnect_at_seq && out_.empty())
      faults_.disconnected = true;
    if (faults_.disconnected) throw TransportError("emulated interferometer: device disconnected");
    if (out_.empty()) generateDue();
    if (!out_.empty()) break;
    // Sleep until the next sample is due (or a reply is queued), within the timeout.
    auto wake = deadline;
    if (streaming_ && config_.paced && !faults_.silent) {
      const double next_due_s = stream_start_s_ + static_cast<double>(next_seq_ - stream_first_seq_) / rate_hz_;
      wake = std::min(wake, machine_.clock().wakeFor(next_due_s));
    }
    if (std::chrono::steady_clock::now() >= deadline) return 0;
    cv_.wait_until(lock, wake);
  }
  return takeBytes(out_, buffer);
}

}  // namespace mtcal::mocks
