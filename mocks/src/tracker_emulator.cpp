#include "mtcal/mocks/tracker_emulator.h"

#include <arpa/inet.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <numbers>

#include "mtcal/drivers/tcp_transport.h"
#include "mtcal/error.h"
#include "mtcal/mocks/random.h"
#include "mtcal/processing/air_index.h"

namespace mtcal::mocks {
namespace tp = drivers::tracker;
namespace {

constexpr std::uint64_t kMeasureStream = 0x7261636b31ULL;  // stationary measurements
constexpr std::uint64_t kContinuousStream = 0x7261636b32ULL;
constexpr std::uint64_t kSpotStream = 0x7261636b33ULL;  // spots on faces
constexpr double kFaceInsetMm = 20.0;

bool sendAll(int fd, const std::string& text) {
  std::size_t sent = 0;
  while (sent < text.size()) {
    const ssize_t n = ::send(fd, text.data() + sent, text.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) return false;
    sent += static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

TrackerEmulatorConfig TrackerEmulatorConfig::forGantry(const VirtualMachineConfig& machine, std::uint64_t seed) {
  TrackerEmulatorConfig c;
  c.seed = seed;
  const auto& x = machine.axes[0];
  const auto& y = machine.axes[1];
  const double top_z = -1200.0;
  const auto block = [&](const char* name, double x0, double y0) {
    return BedBlock{name, x0, x0 + 200.0, y0, y0 + 200.0, top_z, top_z - 300.0};
  };
  c.blocks = {block("A", x.min_mm - 400.0, y.min_mm - 400.0), block("B", x.max_mm + 200.0, y.min_mm - 400.0),
              block("C", x.max_mm + 200.0, y.max_mm + 200.0), block("D", x.min_mm - 400.0, y.max_mm + 200.0)};
  // TB1..TB3 as the patent's three seats close together on the A body; TB4, TB5 farther out
  // (for least-squares fits over more, wider-spread targets); TCP a nest at the tool point.
  c.tool_nests = {{"TB1", {-100.0, 60.0, 200.0}},  {"TB2", {100.0, 60.0, 200.0}},  {"TB3", {0.0, -90.0, 120.0}},
                  {"TB4", {-180.0, -140.0, 40.0}}, {"TB5", {190.0, -120.0, 60.0}}, {"TCP", {0.0, 0.0, 0.0}}};
  c.position_mm = Eigen::Vector3d(x.min_mm - 2500.0, (y.min_mm + y.max_mm) / 2.0, -700.0);
  return c;
}

Eigen::Isometry3d TrackerEmulatorConfig::bedFromTracker() const {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = (Eigen::AngleAxisd(heading_deg * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(level_x_urad * 1e-6, Eigen::Vector3d::UnitX()) *
                Eigen::AngleAxisd(level_y_urad * 1e-6, Eigen::Vector3d::UnitY()))
                   .toRotationMatrix();
  t.translation() = position_mm;
  return t;
}

TrackerEmulator::TrackerEmulator(VirtualMachine& machine, TrackerEmulatorConfig config)
    : machine_(machine), config_(std::move(config)), tracker_from_bed_(config_.bedFromTracker().inverse()) {
  distance_scale_ = distanceScale();
  listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (listener_ < 0 || ::bind(listener_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::listen(listener_, 4) != 0) {
    if (listener_ >= 0) ::close(listener_);
    throw TransportError("tracker emulator: cannot listen on 127.0.0.1");
  }
  socklen_t len = sizeof addr;
  ::getsockname(listener_, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = ntohs(addr.sin_port);
  thread_ = std::thread([this] { serve(); });
}

TrackerEmulator::~TrackerEmulator() {
  stop_ = true;
  thread_.join();
  ::close(listener_);
}

std::unique_ptr<drivers::tracker::TrackerDevice> TrackerEmulator::connect(const std::string& uri) const {
  drivers::tracker::Timeouts timeouts;
  timeouts.command = kEmulatorReplyTimeout;
  timeouts.stall = kEmulatorStallTimeout;
  return std::make_unique<drivers::tracker::TrackerDevice>(std::make_unique<drivers::TcpTransport>("127.0.0.1", port_),
                                                           uri, timeouts);
}

std::vector<std::string> TrackerEmulator::places() const {
  std::vector<std::string> p;
  for (const auto& [name, offset] : config_.tool_nests) p.push_back(name);
  for (const auto& b : config_.blocks) {
    for (const char* face : {".top", ".side1", ".side2"}) p.push_back(b.name + face);
  }
  p.push_back("home");
  return p;
}

void TrackerEmulator::placeReflector(const std::string& place) {
  const auto all = places();
  if (std::find(all.begin(), all.end(), place) == all.end()) {
    std::string known;
    for (const auto& p : all) known += (known.empty() ? "" : ", ") + p;
    throw InputError("tracker emulator: no place '" + place + "' for the reflector (known: " + known + ")");
  }
  std::lock_guard lock(mutex_);
  place_ = place;
  beam_locked_ = true;
  recordReflector();
}

void TrackerEmulator::breakBeam() {
  std::lock_guard lock(mutex_);
  beam_locked_ = false;
  recordReflector();
}

void TrackerEmulator::recordReflector() {
  const double now = machine_.clock().nowS();
  // States older than the stream's next point are not looked up again.
  while (reflector_history_.size() > 1 &&
         reflector_history_[1].from_s <=
             std::min(now, stream_start_s_ + static_cast<double>(stream_next_) / stream_rate_hz_)) {
    reflector_history_.erase(reflector_history_.begin());
  }
  reflector_history_.push_back({now, place_, beam_locked_});
}

const TrackerEmulator::ReflectorState* TrackerEmulator::reflectorAt(double t_s) const {
  const ReflectorState* state = nullptr;
  for (const auto& r : reflector_history_) {
    if (r.from_s > t_s) break;
    state = &r;
  }
  return state;
}

void TrackerEmulator::dropConnection() { drop_ = true; }
void TrackerEmulator::setSilent(bool silent) { silent_ = silent; }

std::uint64_t TrackerEmulator::measurements() const {
  std::lock_guard lock(mutex_);
  return measurement_index_;
}

Eigen::Vector3d TrackerEmulator::truePlaceMm(const std::string& place, double t_s, std::uint64_t index) const {
  std::lock_guard lock(mutex_);
  return placePoint(place, t_s, index);
}

Eigen::Vector3d TrackerEmulator::placePoint(const std::string& place, double t_s, std::uint64_t index) const {
  if (const auto nest = config_.tool_nests.find(place); nest != config_.tool_nests.end()) {
    return machine_.actualPointMm(nest->second, t_s);
  }
  if (place == "home") return config_.bedFromTracker() * Eigen::Vector3d(120.0, 0.0, -250.0);
  const auto dot = place.find('.');
  const std::string block_name = place.substr(0, dot), face = place.substr(dot + 1);
  Eigen::Vector2d bed_centre = Eigen::Vector2d::Zero();
  for (const auto& b : config_.blocks)
    bed_centre += Eigen::Vector2d(b.x_min_mm + b.x_max_mm, b.y_min_mm + b.y_max_mm) / 2.0;
  bed_centre /= static_cast<double>(config_.blocks.size());
  for (const auto& b : config_.blocks) {
    if (b.name != block_name) continue;
    const auto spot = [&](double lo, double hi, std::uint64_t k) {
      const double u = uniformFromKey(mix64(config_.seed ^ kSpotStream) ^ mix64(index * 4 + k));
      return lo + kFaceInsetMm + u * (hi - lo - 2.0 * kFaceInsetMm);
    };
    const double r = reflector_radius_mm_;
    if (face == "top") return {spot(b.x_min_mm, b.x_max_mm, 0), spot(b.y_min_mm, b.y_max_mm, 1), b.top_z_mm + r};
    const bool low_x = (b.x_min_mm + b.x_max_mm) / 2.0 < bed_centre.x(),
               low_y = (b.y_min_mm + b.y_max_mm) / 2.0 < bed_centre.y();
    const double z = spot(b.bottom_z_mm, b.top_z_mm, 2);
    if (face == "side1") return {low_x ? b.x_min_mm - r : b.x_max_mm + r, spot(b.y_min_mm, b.y_max_mm, 1), z};
    return {spot(b.x_min_mm, b.x_max_mm, 0), low_y ? b.y_min_mm - r : b.y_max_mm + r, z};
  }
  throw InputError("tracker emulator: no place '" + place + "'");
}

double TrackerEmulator::distanceScale() const {
  const auto& m = machine_.config();
  const processing::AirState truth{m.air_temp_c, m.air_pressure_pa, m.humidity_pct};
  const processing::AirState host{host_temp_c_, host_pressure_hpa_ * 100.0, host_humidity_pct_};
  return processing::edlenIndex(truth, 632.99) / processing::edlenIndex(host, 632.99);
}

Eigen::Vector3d TrackerEmulator::observed(const Eigen::Vector3d& bed_mm, double integration_ms, std::uint64_t stream,
                                          std::uint64_t index) const {
  const Eigen::Vector3d p = tracker_from_bed_ * bed_mm;
  const double range_m = p.norm() / 1000.0;
  const auto& n = config_.noise;
  const double slow = std::sqrt(1.0 + n.integration_constant_ms / integration_ms);
  const double sigma_d_mm = (n.distance_um + n.distance_um_per_m * range_m) * slow / 1000.0;
  const double sigma_t_mm = (n.transverse_um + n.transverse_um_per_m * range_m) * slow / 1000.0;
  const Eigen::Vector3d radial = p.normalized(), t1 = radial.unitOrthogonal(), t2 = radial.cross(t1);
  const auto z = [&](std::uint64_t k) { return normalFromKey(config_.seed, stream, index * 8 + k); };
  Eigen::Vector3d q = p * distance_scale_ + sigma_d_mm * z(0) * radial + sigma_t_mm * (z(1) * t1 + z(2) * t2);
  if (integration_ms < n.outlier_below_ms &&
      uniformFromKey(mix64(config_.seed ^ stream) ^ mix64(index * 8 + 3)) < n.outlier_probability) {
    q += n.outlier_um / 1000.0 * (z(4) >= 0 ? t1 : Eigen::Vector3d(-t1));
  }
  return q;
}

std::string TrackerEmulator::measureReply(std::uint32_t tag, int integration_ms, double start_s) {
  std::lock_guard lock(mutex_);
  if (!beam_locked_) {
    return tp::formatReply({tp::Reply::Kind::kError, tag, {"4", "beam broken: no reflector locked"}});
  }
  const std::uint64_t index = measurement_index_++;
  const double mid_s = start_s + integration_ms / 2000.0;
  const Eigen::Vector3d q = observed(placePoint(place_, mid_s, index), integration_ms, kMeasureStream, index);
  tp::Point p;
  p.xyz_mm = {q.x(), q.y(), q.z()};
  const auto& n = config_.noise;
  p.rms_um =
      std::hypot(n.distance_um, n.transverse_um) * std::sqrt(1.0 + n.integration_constant_ms);  // one 1 ms reading
  p.time_s = mid_s;
  p.readings = integration_ms;
  return tp::formatReply({tp::Reply::Kind::kOk, tag, tp::pointFields(p)});
}

std::vector<std::string> TrackerEmulator::handle(const std::string& line) {
  tp::Request r;
  try {
    r = tp::parseRequest(line);
  } catch (const ProtocolError& e) {
    return {tp::formatEvent({"ERR", {"2", "malformed", "request"}})};
  }
  const auto ok = [&](std::vector<std::string> fields = {}) {
    return tp::formatReply({tp::Reply::Kind::kOk, r.tag, std::move(fields)});
  };
  const auto err = [&](tp::ErrorCode code, const std::string& text) {
    return tp::formatReply({tp::Reply::Kind::kError, r.tag, {std::to_string(static_cast<int>(code)), text}});
  };
  const double now = machine_.clock().nowS();
  std::lock_guard lock(mutex_);
  if (r.verb == "HELLO") {
    return {ok(tp::helloFields(
        {config_.protocol_major, config_.protocol_minor, config_.model, config_.serial, config_.firmware}))};
  }
  if (r.verb == "STATUS") {
    const std::string state = now < busy_until_s_ ? "BUSY"
                              : streaming_        ? "STREAMING"
                              : initialised_      ? "READY"
                                                  : "NOINIT";
    return {
        ok(tp::statusFields({state, beam_locked_, reflector_, host_temp_c_, host_pressure_hpa_, host_humidity_pct_}))};
  }
  const bool long_command = r.verb == "INIT" || r.verb == "HOME";
  if (long_command && streaming_) return {err(tp::ErrorCode::kStreaming, "stop the continuous measurement first")};
  if (now < busy_until_s_) return {tp::formatReply({tp::Reply::Kind::kBusy, r.tag, {}})};
  if (long_command) {
    // Started by the first request, answered BUSY until done; asked again then: OK.
    if (r.verb == "HOME" && !initialised_) return {err(tp::ErrorCode::kNotInitialised, "send INIT first")};
    const bool done = r.verb == "INIT" ? initialised_ : place_ == "home" && beam_locked_;
    if (done) return {ok()};
    busy_until_s_ = now + (r.verb == "INIT" ? config_.init_s : config_.home_s);
    machine_.clock().letRunTo(busy_until_s_);  // the host polls until then
    if (r.verb == "INIT") initialised_ = true;
    if (r.verb == "HOME") {
      place_ = "home";
      beam_locked_ = true;
      recordReflector();
    }
    return {tp::formatReply({tp::Reply::Kind::kBusy, r.tag, {}})};
  }
  if (r.verb == "UNITS") {
    if (r.args != std::vector<std::string>{"MM", "DEG", "C", "HPA"})
      return {err(tp::ErrorCode::kBadArgument, "units supported: MM DEG C HPA")};
    return {ok()};
  }
  if (r.verb == "ENV") {
    if (r.args.size() != 3) return {err(tp::ErrorCode::kBadArgument, "ENV takes temperature pressure humidity")};
    try {
      const double t = tp::parseNumber(r.args[0], "temperature"), p = tp::parseNumber(r.args[1], "pressure"),
                   h = tp::parseNumber(r.args[2], "humidity");
      if (t < 0 || t > 50 || p < 500 || p > 1200 || h < 0 || h > 100)
        return {err(tp::ErrorCode::kOutOfRange, "environment out of range")};
      host_temp_c_ = t;
      host_pressure_hpa_ = p;
      host_humidity_pct_ = h;
      distance_scale_ = distanceScale();
    } catch (const ProtocolError&) {
      return {err(tp::ErrorCode::kBadArgument, "ENV values must be numbers")};
    }
    return {ok()};
  }
  if (r.verb == "REFLECTOR") {
    if (streaming_) return {err(tp::ErrorCode::kStreaming, "stop the continuous measurement first")};
    const auto radius = r.args.size() == 1 ? tp::reflectorRadiusMm(r.args[0]) : std::nullopt;
    if (!radius) return {err(tp::ErrorCode::kBadArgument, "reflectors: RRR1.5 RRR0.875 RRR0.5")};
    reflector_ = r.args[0];
    reflector_radius_mm_ = *radius;
    return {ok()};
  }
  if (r.verb == "MEAS" || r.verb == "CONT") {
    if (r.verb == "CONT" && r.args == std::vector<std::string>{"STOP"}) {
      streaming_ = false;
      return {ok()};
    }
    if (streaming_) return {err(tp::ErrorCode::kStreaming, "stop the continuous measurement first")};
    if (!initialised_) return {err(tp::ErrorCode::kNotInitialised, "send INIT first")};
    double value = 0.0;
    try {
      if (r.args.size() != 1) throw ProtocolError("argument count");
      value = tp::parseNumber(r.args[0], "argument");
    } catch (const ProtocolError&) {
      return {err(tp::ErrorCode::kBadArgument, r.verb + " takes one number")};
    }
    if (!beam_locked_) return {err(tp::ErrorCode::kBeamBroken, "beam broken: no reflector locked")};
    if (r.verb == "CONT") {
      if (value < 1 || value > tp::kMaxRateHz || value != std::floor(value))
        return {err(tp::ErrorCode::kOutOfRange, "rate 1..1000 points/s")};
      streaming_ = true;
      stream_rate_hz_ = value;
      stream_start_s_ = std::ceil(now * value - 1e-9) / value;  // points on the world's grid of 1/rate
      stream_next_ = 0;
      return {ok()};
    }
    if (value < 1 || value > tp::kMaxIntegrationMs || value != std::floor(value)) {
      return {err(tp::ErrorCode::kOutOfRange, "integration 1..60000 ms")};
    }
    busy_until_s_ = now + value / 1000.0;
    pending_ = Pending{r.tag, static_cast<int>(value), now};  // answered when the integration is over
    machine_.clock().letRunTo(busy_until_s_);                 // the host waits for that answer
    return {};
  }
  return {err(tp::ErrorCode::kUnknownCommand, "unknown command " + r.verb)};
}

void TrackerEmulator::serve() {
  int client = -1;
  drivers::LineDecoder decoder(tp::kMaxLineBytes);
  const auto closeClient = [&] {
    if (client >= 0) ::close(client);
    client = -1;
    pending_.reset();
    std::lock_guard lock(mutex_);
    streaming_ = false;
  };
  while (!stop_) {
    if (client < 0) {
      drop_ = false;
      pollfd p{listener_, POLLIN, 0};
      if (::poll(&p, 1, 20) > 0) {
        client = ::accept(listener_, nullptr, nullptr);
        if (client >= 0) {
          const int one = 1;
          ::setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
          decoder = drivers::LineDecoder(tp::kMaxLineBytes);
        }
      }
      continue;
    }
    if (drop_) {
      closeClient();
      continue;
    }
    bool streaming = false;
    {
      std::lock_guard lock(mutex_);
      streaming = streaming_;
    }
    pollfd p{client, POLLIN, 0};
    const int ready = ::poll(&p, 1, streaming || pending_ ? 1 : 10);
    if (ready > 0) {
      char buffer[4096];
      const ssize_t n = ::recv(client, buffer, sizeof buffer, 0);
      if (n <= 0) {
        closeClient();
        continue;
      }
      decoder.feed(std::span(reinterpret_cast<const std::uint8_t*>(buffer), static_cast<std::size_t>(n)));
    }
    bool ok = true;
    while (auto line = decoder.next()) {
      if (silent_) continue;
      for (const auto& out : handle(*line)) ok = ok && sendAll(client, out);
    }
    const double now = machine_.clock().nowS();
    if (pending_ && now >= pending_->start_s + pending_->integration_ms / 1000.0 && !silent_) {
      ok = ok && sendAll(client, measureReply(pending_->tag, pending_->integration_ms, pending_->start_s));
      pending_.reset();
    }
    if (!silent_) {
      std::string points;
      {
        std::lock_guard lock(mutex_);
        for (int k = 0; streaming_ && k < 5000; ++k) {
          const double t = stream_start_s_ + static_cast<double>(stream_next_) / stream_rate_hz_;
          if (t > now) break;
          const std::uint64_t seq = stream_next_++;
          const ReflectorState* reflector = reflectorAt(t);
          if (!reflector || !reflector->locked) continue;  // no point while the beam is broken: the host sees a gap
          // Noise keyed to the machine's last move and the time from its rest: the same for the
          // same motion whatever the wall clock did (reproducible passes).
          const auto [epoch, rest_s] = machine_.moveEpoch(t);
          const auto key = mix64(epoch) ^ static_cast<std::uint64_t>(std::llround((t - rest_s) * 1e6));
          const Eigen::Vector3d q =
              observed(placePoint(reflector->place, t, 0), 1000.0 / stream_rate_hz_, kContinuousStream, key);
          points += tp::formatEvent(tp::streamPointEvent({static_cast<std::uint32_t>(seq), t, {q.x(), q.y(), q.z()}}));
        }
      }
      if (!points.empty()) ok = ok && sendAll(client, points);
    }
    if (!ok) closeClient();
  }
  if (client >= 0) ::close(client);
}

}  // namespace mtcal::mocks
