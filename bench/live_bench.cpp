// The live page against a 50 kHz interferometer stream: a recorder writes 50 000 raw samples a
// second into a running run (batches every 10 ms, a capture every 100 ms), as the stream
// recorder does, while a WebSocket client watches the run through the real server
// (`/api/live/N`). Reported: the updates a second the page receives (the stream decimated,
// goal <= 30), the captures lost (goal 0), and the CPU share of the server's thread against
// the recorder's own in the same run (the reference). docs/performance.md gives the figures.

#include <benchmark/benchmark.h>
#include <pthread.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <thread>

#include "mtcal/storage/heartbeat.h"
#include "mtcal/storage/store.h"
#include "mtcal/web/server.h"

namespace {

using namespace mtcal;
namespace beast = boost::beast;
using tcp = boost::asio::ip::tcp;

constexpr int kRateHz = 50000, kBatchMs = 10, kCaptureEveryMs = 100;

/// CPU seconds a thread has used.
double cpuSeconds(pthread_t thread) {
  clockid_t clock = 0;
  pthread_getcpuclockid(thread, &clock);
  timespec t{};
  clock_gettime(clock, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

void BM_LivePageAt50kHz(benchmark::State& state) {
  const double seconds = static_cast<double>(state.range(0));
  for (auto _ : state) {
    std::unique_ptr<storage::Heartbeat> heartbeat;
    const auto path = (std::filesystem::temp_directory_path() / "mtcal_bench_live.sqlite").string();
    for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path + suffix);
    storage::Id run = 0;
    {
      storage::Store store(path);
      // Alive: this process beats for the archive, as a recording session does.
      heartbeat = std::make_unique<storage::Heartbeat>(path);
      storage::NewRun r;
      r.campaign_id = store.addCampaign(store.ensureMachine("bench", "", "{}"), "bench");
      r.axis = "X";
      r.name = "50 kHz";
      run = store.addRun(r);
    }
    web::ServerOptions options;
    options.db_path = path;
    options.port = 0;
    options.read_only = true;  // a station's dashboard beside the recording
    web::Server server(options);
    std::thread serving([&] { server.run(); });

    boost::asio::io_context io;
    tcp::resolver resolver(io);
    beast::websocket::stream<beast::tcp_stream> ws(io);
    beast::get_lowest_layer(ws).connect(resolver.resolve("127.0.0.1", std::to_string(server.port())));
    ws.handshake("127.0.0.1", "/api/live/" + std::to_string(run));

    // The recorder: real time, 50 kHz in 10 ms batches, a capture every 100 ms.
    std::int64_t written_captures = 0, written_samples = 0;
    double recorder_cpu_s = 0.0;
    std::thread recording([&] {
      storage::Store store(path);
      const auto start = std::chrono::steady_clock::now();
      const int batches = static_cast<int>(seconds * 1000.0 / kBatchMs);
      std::vector<storage::SampleRecord> batch(kRateHz * kBatchMs / 1000);
      for (int b = 0; b < batches; ++b) {
        std::this_thread::sleep_until(start + std::chrono::milliseconds(kBatchMs * (b + 1)));
        for (auto& s : batch) {
          s.device_seq = written_samples;
          s.device_time_ns = written_samples * (1000000000 / kRateHz);
          s.value = 50.0 + 1e-6 * static_cast<double>(written_samples % 1000);
          s.signal_pct = 90;
          ++written_samples;
        }
        store.appendSamples(run, batch);
        if ((b + 1) % (kCaptureEveryMs / kBatchMs) == 0) {
          storage::TargetRecord t;
          t.seq = written_captures++;
          t.target_mm = 50.0 + static_cast<double>(t.seq);
          t.deviation_um = 0.1 * static_cast<double>(t.seq % 7);
          store.addTarget(run, t, {});
        }
      }
      store.setRunStatus(run, storage::run_status::kCompleted);
      recorder_cpu_s = cpuSeconds(pthread_self());
    });

    const auto start = std::chrono::steady_clock::now();
    const double server_cpu_before = cpuSeconds(serving.native_handle());
    std::int64_t messages = 0, stream_messages = 0, captures = 0;
    for (;;) {
      beast::flat_buffer buffer;
      beast::error_code ec;
      ws.read(buffer, ec);
      if (ec) break;  // closed once the run has ended
      const auto m = nlohmann::json::parse(beast::buffers_to_string(buffer.data()));
      ++messages;
      stream_messages += m["type"] == "stream";
      captures += m["type"] == "capture";
    }
    const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double server_cpu_s = cpuSeconds(serving.native_handle()) - server_cpu_before;
    recording.join();
    server.stop();
    serving.join();

    state.SetIterationTime(wall_s);
    state.counters["samples_written"] = static_cast<double>(written_samples);
    state.counters["captures_lost"] = static_cast<double>(written_captures - captures);
    state.counters["stream_updates_per_s"] = static_cast<double>(stream_messages) / wall_s;
    state.counters["messages_per_s"] = static_cast<double>(messages) / wall_s;
    state.counters["server_cpu_share"] = server_cpu_s / wall_s;
    state.counters["recorder_cpu_share"] = recorder_cpu_s / wall_s;
  }
}
BENCHMARK(BM_LivePageAt50kHz)->Arg(10)->Unit(benchmark::kMillisecond)->UseManualTime()->Iterations(3);

}  // namespace
