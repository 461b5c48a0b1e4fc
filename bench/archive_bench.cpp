// The dashboard's archive page on an archive of 10 000 runs: what `GET /api/runs` costs through
// the real server (Beast over loopback, the services layer, SQLite, the JSON), against the
// physical reference in the same process: a bare prepared SELECT of the same rows' columns.
// docs/performance.md gives the figures and their ratio.

#include <benchmark/benchmark.h>

#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <filesystem>
#include <thread>

#include "mtcal/storage/store.h"
#include "mtcal/web/server.h"

namespace {

using namespace mtcal;
namespace beast = boost::beast;
using tcp = boost::asio::ip::tcp;

constexpr int kRuns = 10000, kRunsPerCampaign = 100;

/// An archive of 10 000 completed linear runs on X, Y and Z (made once per process).
const std::string& archive() {
  static const std::string path = [] {
    const auto p = (std::filesystem::temp_directory_path() / "mtcal_bench_archive.sqlite").string();
    for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(p + suffix);
    storage::Store store(p);
    storage::Transaction tx(store.database());
    const auto machine = store.ensureMachine("bench machine", "", "{}");
    storage::Id campaign = 0;
    for (int i = 0; i < kRuns; ++i) {
      if (i % kRunsPerCampaign == 0) campaign = store.addCampaign(machine, "campaign " + std::to_string(i));
      storage::NewRun r;
      r.campaign_id = campaign;
      r.axis = std::string(1, "XYZ"[i % 3]);
      r.name = "run " + std::to_string(i);
      r.status = storage::run_status::kCompleted;
      store.addRun(r);
    }
    tx.commit();
    return p;
  }();
  return path;
}

void BM_PlainSqlQuery(benchmark::State& state) {
  storage::Store store(archive(), storage::Open::kReadOnly);
  storage::Statement select(
      store.database(),
      "SELECT r.id, r.campaign_id, c.name, m.name, r.kind, r.axis, r.name, r.status, r.started_at "
      "FROM runs r JOIN campaigns c ON c.id = r.campaign_id JOIN machines m ON m.id = "
      "c.machine_id ORDER BY r.id");
  for (auto _ : state) {
    std::int64_t rows = 0;
    select.reset();
    while (select.step()) rows += select.getInt(0) > 0;
    benchmark::DoNotOptimize(rows);
    if (rows != kRuns) state.SkipWithError("not every run read");
  }
  state.SetItemsProcessed(state.iterations() * kRuns);
}
BENCHMARK(BM_PlainSqlQuery)->Unit(benchmark::kMillisecond)->UseRealTime();

/// GET `target` from a server on loopback, the answer's body.
void archivePage(benchmark::State& state, const std::string& target, std::size_t expected_bytes_at_least) {
  web::ServerOptions o;
  o.db_path = archive();
  o.port = 0;
  o.read_only = true;
  web::Server server(o);
  std::thread thread([&] { server.run(); });
  boost::asio::io_context io;
  tcp::resolver resolver(io);
  const auto endpoints = resolver.resolve("127.0.0.1", std::to_string(server.port()));
  for (auto _ : state) {
    beast::tcp_stream stream(io);
    stream.connect(endpoints);
    beast::http::request<beast::http::empty_body> req(beast::http::verb::get, target, 11);
    req.set(beast::http::field::host, "127.0.0.1");
    beast::http::write(stream, req);
    beast::flat_buffer buffer;
    beast::http::response_parser<beast::http::string_body> parser;
    parser.body_limit(64 * 1024 * 1024);
    beast::http::read(stream, buffer, parser);
    if (parser.get().result_int() != 200 || parser.get().body().size() < expected_bytes_at_least)
      state.SkipWithError("not the archive's runs");
    beast::error_code ignored;
    stream.socket().shutdown(tcp::socket::shutdown_both, ignored);
  }
  server.stop();
  thread.join();
}

/// The page the dashboard asks for: the first 500 runs (its default page).
void BM_ArchivePage(benchmark::State& state) {
  archivePage(state, "/api/runs", 100 * 500);
  state.SetItemsProcessed(state.iterations() * 500);
}
BENCHMARK(BM_ArchivePage)->Unit(benchmark::kMillisecond)->UseRealTime();

/// The last page of the runs of one axis (3334 of 10 000 filtered, the last 334 answered).
void BM_ArchivePageOneAxis(benchmark::State& state) {
  archivePage(state, "/api/runs?axis=Y&kind=linear&offset=3000", 100 * 300);
  state.SetItemsProcessed(state.iterations() * 334);
}
BENCHMARK(BM_ArchivePageOneAxis)->Unit(benchmark::kMillisecond)->UseRealTime();

/// Every run in one answer (limit=10000): what the JSON of 10 000 runs costs.
void BM_ArchiveAllRuns(benchmark::State& state) {
  archivePage(state, "/api/runs?limit=10000", 100 * static_cast<std::size_t>(kRuns));
  state.SetItemsProcessed(state.iterations() * kRuns);
}
BENCHMARK(BM_ArchiveAllRuns)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
