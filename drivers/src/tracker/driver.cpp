#include "mtcal/drivers/tracker/driver.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>
#include <cmath>
#include <thread>

#include "../stream_read.h"
#include "mtcal/error.h"

namespace mtcal::drivers::tracker {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

TrackerDevice::TrackerDevice(std::unique_ptr<TcpTransport> transport, std::string uri, Timeouts timeouts)
    : transport_(std::move(transport)), uri_(std::move(uri)), timeouts_(timeouts) {
  hello_ = parseHello(command("HELLO", {}, timeouts_.command));
}

TrackerDevice::~TrackerDevice() {
  if (streaming_) {
    try {
      stopStream();
    } catch (const std::exception& e) {
      spdlog::warn("{}: stopping the continuous measurement on close: {}", uri_, e.what());
    }
  }
}

DeviceInfo TrackerDevice::info() const { return {uri_, "tracker", hello_.model, hello_.serial, hello_.firmware}; }

void TrackerDevice::refuseWhileStreaming(const std::string& verb) const {
  if (streaming_) throw DeviceError(fmt::format("{}: {}: stop the continuous measurement first", uri_, verb));
}

std::string TrackerDevice::readLine(Clock::time_point deadline, const std::string& what) {
  for (;;) {
    if (auto line = decoder_.next()) return *line;
    const auto left = std::chrono::duration_cast<milliseconds>(deadline - Clock::now());
    if (left.count() <= 0) throw TimeoutError(fmt::format("{}: {}: no reply in time", uri_, what));
    std::array<std::uint8_t, 4096> buffer{};
    const std::size_t n = transport_->read(buffer, left);
    decoder_.feed(std::span(buffer.data(), n));
  }
}

Reply TrackerDevice::exchange(const std::string& verb, const std::vector<std::string>& args,
                              Clock::time_point deadline) {
  for (;;) {
    const Request request{next_tag_++, verb, args};
    if (next_tag_ == 0) next_tag_ = 1;
    const std::string line = formatRequest(request);
    const auto left = std::max(milliseconds(1), std::chrono::duration_cast<milliseconds>(deadline - Clock::now()));
    transport_->write(std::span(reinterpret_cast<const std::uint8_t*>(line.data()), line.size()), left);
    for (;;) {
      const Message message = parseMessage(readLine(deadline, verb));
      if (const auto* event = std::get_if<Event>(&message)) {
        handleEvent(*event);
        continue;
      }
      const Reply& reply = std::get<Reply>(message);
      if (reply.tag != request.tag) {
        ++bad_lines_;  // a late reply to an earlier, timed-out command
        continue;
      }
      if (reply.kind != Reply::Kind::kBusy) return reply;
      break;
    }
    if (Clock::now() + timeouts_.busy_retry >= deadline) {
      throw TimeoutError(fmt::format("{}: {}: the tracker stayed busy until the deadline", uri_, verb));
    }
    std::this_thread::sleep_for(timeouts_.busy_retry);
  }
}

std::vector<std::string> TrackerDevice::command(const std::string& verb, std::vector<std::string> args,
                                                milliseconds timeout) {
  for (int attempt = 0;; ++attempt) {
    try {
      if (!transport_->connected()) reconnectAndRestore();
      const Reply reply = exchange(verb, args, Clock::now() + timeout);
      if (reply.kind == Reply::Kind::kError) {
        std::string sent = verb;
        for (const auto& a : args) sent += " " + a;
        throw DeviceError(fmt::format("{}: {}: error {} ({}): {}", uri_, sent, reply.error_code(),
                                      errorName(reply.error_code()), reply.error_text()));
      }
      return reply.fields;
    } catch (const TimeoutError&) {
      throw;
    } catch (const TransportError& e) {
      if (attempt > 0) throw;
      spdlog::warn("{}: {}: {}; reconnecting", uri_, verb, e.what());
    }
  }
}

void TrackerDevice::reconnectAndRestore() {
  transport_->reconnect();
  decoder_ = LineDecoder(kMaxLineBytes);
  ++reconnects_;
  const auto deadline = [&] { return Clock::now() + timeouts_.command; };
  const auto ok = [&](const Reply& r, const char* what) {
    if (r.kind != Reply::Kind::kOk)
      throw DeviceError(fmt::format("{}: restoring {} after a reconnect failed: {}", uri_, what, r.error_text()));
    return r.fields;
  };
  hello_ = parseHello(ok(exchange("HELLO", {}, deadline()), "the session"));
  if (units_set_) ok(exchange("UNITS", {"MM", "DEG", "C", "HPA"}, deadline()), "the units");
  if (environment_) {
    ok(exchange("ENV",
                {fmt::format("{:.2f}", environment_->air_temp_c), fmt::format("{:.2f}", environment_->pressure_hpa),
                 fmt::format("{:.1f}", environment_->humidity_pct)},
                deadline()),
       "the environment");
  }
  if (!reflector_.empty()) ok(exchange("REFLECTOR", {reflector_}, deadline()), "the reflector");
}

void TrackerDevice::initialise() {
  refuseWhileStreaming("INIT");
  command("INIT", {}, timeouts_.initialise);
}

void TrackerDevice::setUnits() {
  refuseWhileStreaming("UNITS");
  command("UNITS", {"MM", "DEG", "C", "HPA"}, timeouts_.command);
  units_set_ = true;
}

void TrackerDevice::setEnvironment(const Environment& env) {
  refuseWhileStreaming("ENV");
  if (!(env.air_temp_c >= 0.0 && env.air_temp_c <= 50.0) ||
      !(env.pressure_hpa >= 500.0 && env.pressure_hpa <= 1200.0) ||
      !(env.humidity_pct >= 0.0 && env.humidity_pct <= 100.0)) {
    throw InputError(fmt::format("{}: environment {} C, {} hPa, {} % outside 0..50 C, 500..1200 hPa, 0..100 %", uri_,
                                 env.air_temp_c, env.pressure_hpa, env.humidity_pct));
  }
  command("ENV",
          {fmt::format("{:.2f}", env.air_temp_c), fmt::format("{:.2f}", env.pressure_hpa),
           fmt::format("{:.1f}", env.humidity_pct)},
          timeouts_.command);
  environment_ = env;
}

void TrackerDevice::setReflector(const std::string& name) {
  refuseWhileStreaming("REFLECTOR");
  if (name.empty() || name.find(' ') != std::string::npos) {
    throw InputError(fmt::format("{}: reflector name '{}' must be one word", uri_, name));
  }
  command("REFLECTOR", {name}, timeouts_.command);
  reflector_ = name;
}

void TrackerDevice::goHome() {
  refuseWhileStreaming("HOME");
  command("HOME", {}, timeouts_.initialise);
}

Point TrackerDevice::measure(int integration_ms) {
  refuseWhileStreaming("MEAS");
  if (integration_ms < 1 || integration_ms > kMaxIntegrationMs) {
    throw InputError(fmt::format("{}: integration time {} ms outside 1..{}", uri_, integration_ms, kMaxIntegrationMs));
  }
  return parsePoint(
      command("MEAS", {std::to_string(integration_ms)}, timeouts_.command + milliseconds(integration_ms)));
}

Status TrackerDevice::status() {
  refuseWhileStreaming("STATUS");
  return parseStatus(command("STATUS", {}, timeouts_.command));
}

void TrackerDevice::handleEvent(const Event& event) {
  if (event.kind == "PT") {
    if (!sink_) {
      ++bad_lines_;  // a stream point after the stream was stopped and handed back
      return;
    }
    const StreamPoint p = parseStreamPoint(event);
    if (next_seq_ && p.seq != *next_seq_) lost_ += p.seq - *next_seq_;
    next_seq_ = p.seq + 1;
    std::array<Sample, 3> samples{};
    for (int k = 0; k < 3; ++k) {
      auto& s = samples[static_cast<std::size_t>(k)];
      s.seq = p.seq;
      s.device_time_ns = static_cast<std::int64_t>(std::llround(p.time_s * 1e9));
      s.value = p.xyz_mm[static_cast<std::size_t>(k)];
      s.signal_pct = 100;
      s.channel = k + 1;
    }
    sink_->push(samples);
    samples_ += 1;
  } else if (event.kind == "BEAM") {
    spdlog::warn("{}: beam {}", uri_, event.fields.empty() ? "?" : event.fields[0]);
  } else {
    ++bad_lines_;
  }
}

void TrackerDevice::startStream(std::uint32_t rate_hz, SampleSink& sink) {
  refuseWhileStreaming("CONT");
  if (rate_hz < 1 || rate_hz > kMaxRateHz) {
    throw InputError(fmt::format("{}: continuous rate {} points/s outside 1..{}", uri_, rate_hz, kMaxRateHz));
  }
  sink_ = &sink;
  next_seq_.reset();
  samples_ = 0;
  lost_ = 0;
  try {
    command("CONT", {std::to_string(rate_hz)}, timeouts_.command);
  } catch (...) {
    sink_ = nullptr;
    throw;
  }
  streaming_ = true;
  reader_.start("", [this] { readerLoop(); });
}

void TrackerDevice::readerLoop() {
  auto last_data = Clock::now();
  while (!reader_.stopping()) {
    while (auto line = decoder_.next()) {
      const Message message = parseMessage(*line);
      if (const auto* event = std::get_if<Event>(&message)) {
        handleEvent(*event);
        last_data = Clock::now();
      } else {
        ++bad_lines_;  // no command is pending while streaming
      }
    }
    std::array<std::uint8_t, 4096> buffer{};
    const std::size_t n = readOrStall(*transport_, buffer, timeouts_.read, timeouts_.stall, last_data, uri_);
    decoder_.feed(std::span(buffer.data(), n));
  }
}

StreamStats TrackerDevice::stopStream() {
  if (!streaming_) return stats();
  std::exception_ptr error = reader_.stopAndTakeError();
  streaming_ = false;
  if (!error) {
    try {
      command("CONT", {"STOP"}, timeouts_.command);  // points still in flight reach the sink
    } catch (...) {
      error = std::current_exception();
    }
  }
  sink_ = nullptr;
  if (error) std::rethrow_exception(error);
  return stats();
}

void TrackerDevice::poll() { reader_.rethrowIfFailed(); }

std::vector<StreamChannel> TrackerDevice::streamChannels() const {
  return {{1, "x", "position", "mm", "", ""}, {2, "y", "position", "mm", "", ""}, {3, "z", "position", "mm", "", ""}};
}

StreamStats TrackerDevice::stats() const {
  StreamStats s;
  s.samples = samples_;
  s.lost_samples = lost_;
  s.crc_errors = bad_lines_;
  return s;
}

}  // namespace mtcal::drivers::tracker
