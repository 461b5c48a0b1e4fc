#include "mtcal/mocks/probe_emulator.h"

#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>

#include "byte_queue.h"
#include "mtcal/error.h"
#include "mtcal/mocks/random.h"

namespace mtcal::mocks {
namespace pb = drivers::probes;
namespace {
constexpr std::uint64_t kProbeNoiseStream = 300;
constexpr std::size_t kOutputBufferBytes = 8192;  ///< the box's transmit buffer
}  // namespace

ProbeBoxEmulator::ProbeBoxEmulator(VirtualMachine& machine, ProbeBoxEmulatorConfig config)
    : machine_(machine), config_(std::move(config)), tare_um_(static_cast<std::size_t>(config_.channels), 0.0) {
  config_.zero_um.resize(static_cast<std::size_t>(config_.channels), 0.0);
}

void ProbeBoxEmulator::updateFaults(const std::function<void(ProbeBoxFaults&)>& change) {
  {
    std::lock_guard lock(mutex_);
    change(faults_);
  }
  cv_.notify_all();
}

void ProbeBoxEmulator::trigger(double t_s) {
  {
    std::lock_guard lock(mutex_);
    if (!triggered_ || faults_.silent) return;
    pb::StreamLine s;
    s.latched = true;
    s.seq = next_latch_++;
    s.time_us = std::llround(t_s * 1e6);
    s.channels = readAll(t_s, s.seq);
    send(pb::formatStreamLine(s));
  }
  cv_.notify_all();
}

void ProbeBoxEmulator::setMeasuring(int component) {
  if (component != 1 && component != 2) throw InputError("probe box emulator: the probes read along Y (1) or Z (2)");
  std::lock_guard lock(mutex_);
  config_.measuring = component;
  cached_epoch_ = {~std::uint64_t{0}, 0.0};
}

ToolOffset ProbeBoxEmulator::probeOffset(int index) const {
  ToolOffset o = config_.base_offset_mm;
  o[static_cast<std::size_t>(config_.axis)] += index * config_.spacing_mm;
  return o;
}

void ProbeBoxEmulator::setOnReferenceFlat(bool on) {
  std::lock_guard lock(mutex_);
  on_reference_flat_ = on;
  cached_epoch_ = {~std::uint64_t{0}, 0.0};  // the cached readings were of the other surface
}

double ProbeBoxEmulator::trueReadingUm(int channel, double x_mm) const {
  const int i = channel - 1;
  const auto along = static_cast<std::size_t>(config_.axis);
  const double shift_um = machine_.staticErrorUm(config_.axis, probeOffset(i), x_mm, +1);
  const double x_probe = x_mm + i * config_.spacing_mm + config_.base_offset_mm[along] + shift_um / 1000.0;
  const double d = machine_.staticErrorUm(config_.axis, probeOffset(i), x_mm, +1, config_.measuring);
  return config_.profile_um.value(x_probe) - d + config_.zero_um[static_cast<std::size_t>(i)];
}

std::vector<double> ProbeBoxEmulator::noiseFreeUm(double t) const {
  const auto along = static_cast<std::size_t>(config_.axis);
  const double x = machine_.positionsAt(t)[along];
  std::vector<double> out;
  for (int i = 0; i < config_.channels; ++i) {
    // The tip is where the machine put it: the commanded position plus its displacement, so a
    // positioning (step) error of the carriage moves the probes along the guideway too.
    const Eigen::Vector3d d_um = machine_.pointErrorUm(probeOffset(i), t);
    const double x_probe =
        x + i * config_.spacing_mm + config_.base_offset_mm[along] + d_um(static_cast<int>(along)) / 1000.0;
    const double surface_um = on_reference_flat_ ? 0.0 : config_.profile_um.value(x_probe);
    out.push_back(surface_um - d_um(config_.measuring) + config_.zero_um[static_cast<std::size_t>(i)]);
  }
  return out;
}

std::vector<pb::Reading> ProbeBoxEmulator::readAll(double t, std::optional<std::uint64_t> latch) {
  // Readings live on a grid of the stream period anchored to the last move's in-position time:
  // the k-th reading after a move sees the same machine state and the same noise whatever the
  // wall clock did, so a seed gives the same campaign. A latched reading is taken at its
  // pulse's time exactly, its noise keyed to the pulse's count.
  const auto epoch = machine_.moveEpoch(t);
  const auto slot = static_cast<std::int64_t>(std::floor((t - epoch.second) * rate_hz_ + 1e-6));
  const double t_grid = latch ? t : slot >= 0 ? epoch.second + static_cast<double>(slot) / rate_hz_ : t;
  const std::uint64_t key =
      latch ? (std::uint64_t{1} << 62) + *latch : (epoch.first << 32) ^ static_cast<std::uint64_t>(slot);
  // Settled: past the transient of the last move, or no move yet (standing since the start).
  // A machine with a thermal state drifts at rest: nothing is constant then.
  const bool settled =
      (epoch.first == 0 || t_grid >= epoch.second + machine_.settledAfterS()) && machine_.thermal() == nullptr;
  std::vector<double> um;
  if (epoch == cached_epoch_ && settled) {
    um = cached_um_;
  } else {
    um = noiseFreeUm(t_grid);
    if (settled) {
      cached_epoch_ = epoch;
      cached_um_ = um;
    }
  }
  std::vector<pb::Reading> out;
  for (int i = 0; i < config_.channels; ++i) {
    const double noise = config_.noise_um * normalFromKey(machine_.config().seed, kProbeNoiseStream,
                                                          key * 16 + static_cast<std::uint64_t>(i));
    const double value_um = um[static_cast<std::size_t>(i)] + noise - tare_um_[static_cast<std::size_t>(i)];
    pb::Reading r{value_um / 1000.0, pb::ChannelStatus::kOk};
    if (r.value_mm > config_.range_mm) r.status = pb::ChannelStatus::kOverRange;
    if (r.value_mm < -config_.range_mm) r.status = pb::ChannelStatus::kUnderRange;
    if (faults_.over_range_channel == i + 1) r = {config_.range_mm * 1.05, pb::ChannelStatus::kOverRange};
    if (faults_.no_probe_channel == i + 1) r = {0.0, pb::ChannelStatus::kNoProbe};
    out.push_back(r);
  }
  return out;
}

void ProbeBoxEmulator::send(std::string line) {
  if (faults_.garble_next_lines > 0) {
    --faults_.garble_next_lines;
    for (std::size_t i = 0; i + 2 < line.size(); i += 3) line[i] = '#';
  }
  appendBytes(out_, line);
}

void ProbeBoxEmulator::execute(const std::string& text) {
  pb::Command c{};
  try {
    c = pb::parseCommand(text);
  } catch (const ProtocolError& e) {
    send(pb::formatError(1, "unknown or malformed command"));
    return;
  }
  switch (c.kind) {
    case pb::Command::Kind::kIdentify:
      send(pb::formatIdentity({"MTCAL", config_.model, config_.serial, config_.firmware}));
      return;
    case pb::Command::Kind::kChannels:
      send(pb::formatChannels({config_.channels, config_.range_mm}));
      return;
    case pb::Command::Kind::kRead: {
      if (c.channel > config_.channels) return send(pb::formatError(2, "no such channel"));
      auto all = readAll(machine_.clock().nowS());
      if (c.channel > 0) all = {all[static_cast<std::size_t>(c.channel - 1)]};
      send(pb::formatValues(all));
      return;
    }
    case pb::Command::Kind::kZero: {
      if (c.channel > config_.channels) return send(pb::formatError(2, "no such channel"));
      // The box averages its internal readings for the tare: the reading without its noise.
      const auto um = noiseFreeUm(machine_.clock().nowS());
      for (int i = 0; i < config_.channels; ++i) {
        if (c.channel == 0 || c.channel == i + 1)
          tare_um_[static_cast<std::size_t>(i)] = um[static_cast<std::size_t>(i)];
      }
      send(pb::formatOk());
      return;
    }
    case pb::Command::Kind::kRate:
      if (c.rate_hz < 1 || c.rate_hz > pb::kMaxRateHz) return send(pb::formatError(3, "rate must be 1..1000 Hz"));
      rate_hz_ = c.rate_hz;
      send(pb::formatOk());
      return;
    case pb::Command::Kind::kTrigger:
      triggered_ = c.on;
      next_latch_ = 0;
      send(pb::formatOk());
      return;
    case pb::Command::Kind::kStream:
      streaming_ = c.on;
      stream_start_s_ = machine_.clock().nowS();
      stream_first_seq_ = next_seq_;  // sequence numbers keep counting across streams
      send(pb::formatOk());
      return;
  }
}

void ProbeBoxEmulator::receive(std::span<const std::uint8_t> bytes) {
  {
    std::lock_guard lock(mutex_);
    decoder_.feed(bytes);
    while (auto line = decoder_.next()) {
      if (!faults_.silent) execute(*line);
    }
  }
  cv_.notify_all();
}

std::size_t ProbeBoxEmulator::transmit(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::unique_lock lock(mutex_);
  for (;;) {
    if (streaming_ && !faults_.silent) {
      // Stream lines time-stamped up to now on the world clock since the stream started. A
      // line that finds the box's output buffer full is lost (the host sees the sequence gap),
      // as on a real box whose host does not keep up; replies then never wait behind more than
      // that buffer. In lock step the world waits for the host instead: the line is made
      // later, with its own time stamp.
      const double elapsed = machine_.clock().nowS() - stream_start_s_;
      const auto due = static_cast<std::uint64_t>(std::max(0.0, std::floor(elapsed * rate_hz_ + 1e-6) + 1.0));
      while (next_seq_ - stream_first_seq_ < due) {
        if (out_.size() >= kOutputBufferBytes) {
          if (machine_.clock().lockStep()) break;
          ++next_seq_;
          continue;
        }
        pb::StreamLine s;
        s.seq = next_seq_++;
        const double t = stream_start_s_ + static_cast<double>(s.seq - stream_first_seq_) / rate_hz_;
        s.time_us = std::llround(t * 1e6);
        s.channels = readAll(t);
        send(pb::formatStreamLine(s));
      }
    }
    if (!out_.empty()) break;
    if (std::chrono::steady_clock::now() >= deadline) return 0;
    auto wake = deadline;
    if (streaming_) {
      wake = std::min(wake, machine_.clock().wakeFor(stream_start_s_ +
                                                     static_cast<double>(next_seq_ - stream_first_seq_) / rate_hz_));
    }
    cv_.wait_until(lock, wake);
  }
  return takeBytes(out_, buffer);
}

PtyLink::PtyLink(Receive receive, Transmit transmit) : receive_(std::move(receive)), transmit_(std::move(transmit)) {
  char name[256] = {};
  if (openpty(&master_, &slave_, name, nullptr, nullptr) != 0) {
    throw TransportError(std::string("cannot open a pseudo-terminal: ") + std::strerror(errno));
  }
  slave_path_ = name;
  fcntl(master_, F_SETFL, fcntl(master_, F_GETFL) | O_NONBLOCK);  // never block the pump on a host that does not read
  termios raw{};
  tcgetattr(slave_, &raw);
  cfmakeraw(&raw);  // no echo, no line editing: a plain byte pipe like a serial line
  tcsetattr(slave_, TCSANOW, &raw);
  thread_ = std::thread([this] { pump(); });
}

PtyLink::~PtyLink() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  close(master_);
  close(slave_);
}

void PtyLink::pump() {
  pthread_setname_np(pthread_self(), "mtcal-pty");
  std::array<std::uint8_t, 4096> buffer{};
  while (!stop_) {
    pollfd p{master_, POLLIN, 0};
    if (poll(&p, 1, 2) > 0 && (p.revents & POLLIN)) {
      const ssize_t n = ::read(master_, buffer.data(), buffer.size());
      if (n > 0) receive_({buffer.data(), static_cast<std::size_t>(n)});
    }
    const std::size_t out = transmit_(buffer, std::chrono::milliseconds(2));
    for (std::size_t done = 0; done < out && !stop_;) {
      const ssize_t w = ::write(master_, buffer.data() + done, out - done);
      if (w > 0) {
        done += static_cast<std::size_t>(w);
      } else if (errno == EAGAIN || errno == EINTR) {
        pollfd p{master_, POLLOUT, 0};
        poll(&p, 1, 2);
      } else {
        break;
      }
    }
  }
}

}  // namespace mtcal::mocks
