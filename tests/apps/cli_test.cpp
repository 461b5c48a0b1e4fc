#include "mtcal/app/cli.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>
#include <tuple>

#include "../support/command_output.h"
#include "../support/temp_dir.h"
#include "../support/time_scale.h"
#include "mtcal/services/version.h"

namespace mtcal::app {
namespace {

// Drives the command line exactly as the executable does, on a fresh database per test.
class CliTest : public ::testing::Test {
 protected:
  struct Result {
    int code;
    std::string out, err;
    nlohmann::json json() const { return nlohmann::json::parse(out); }
  };
  Result run(std::vector<std::string> args, const std::atomic<bool>* stop = nullptr) {
    args.insert(args.begin(), {"--db", db_});
    std::ostringstream out, err;
    const int code = runCli(args, out, err, stop);
    return {code, out.str(), err.str()};
  }
  static std::string data(const char* name) { return std::string(MTCAL_TEST_DATA_DIR) + "/" + name; }

  mtcal::testing::TempDir dir_;
  std::string db_ = dir_.file("mtcal.sqlite");
};

TEST_F(CliTest, AnalyzeLinearUnderAStandardAndCompareTwoRuns) {
  for (const char* axis : {"X", "X", "Y"})
    ASSERT_EQ(run({"import", "linear", data("linear_deviation.csv"), "--axis", axis}).code, 0);
  auto r = run({"analyze", "linear", "1", "--standard", "vdi3441", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  auto j = r.json();
  EXPECT_EQ(j["title"], "VDI/DGQ 3441:1977");
  EXPECT_FALSE(j["definitions_verified"].get<bool>());
  EXPECT_EQ(j["figures"][1]["symbol"], "Pa");
  EXPECT_DOUBLE_EQ(j["figures"][1]["value_um"].get<double>(), 3.25);  // the range of the bidirectional means (M)
  EXPECT_FALSE(j.contains("simulation_truth"));                       // an imported run: no truth
  r = run({"compare", "1", "2"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("axis X, ISO 230-2:2014: run 1 (before) and run 2 (after)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  E                    5.00 um   5.00 um  +0.00 um (+0 %)"), std::string::npos) << r.out;
  r = run({"compare", "1", "2", "--json"});
  ASSERT_EQ(r.code, 0);
  EXPECT_DOUBLE_EQ(r.json()["figures"][0]["change_um"].get<double>(), 0.0);
  EXPECT_EQ(r.json()["after"]["means"].size(), 2u);
  r = run({"compare", "1", "3"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("run 1 measured axis X and run 3 axis Y: compare runs of one axis"), std::string::npos) << r.err;
  r = run({"compare", "1", "1"});
  EXPECT_NE(r.out.find("warning: run 1 compared with itself"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("warning: run 1: only 2 cycle(s) at some target"), std::string::npos) << r.out;
  r = run({"compensate", "1", "--controller", "linuxcnc", "--axis-index", "-1"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--axis-index -1: an axis' number is 0 to 15"), std::string::npos) << r.err;
  r = run({"compensate", "1", "--controller", "haas"});  // a model's volumetric table is named too
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("unknown controller 'haas' (one of: csv, linuxcnc"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("; of a model, also isg-volumetric: its volumetric table)"), std::string::npos) << r.err;
  // An empty file or folder name is not stdout, nor the table left out.
  for (const auto& [args, what] : std::vector<std::pair<std::vector<std::string>, std::string>>{
           {{"compensate", "1", "-o", ""}, "a file name"},
           {{"compensate", "1", "--existing", ""}, "a file name"},
           {{"export", "1", "--csv", ""}, "a folder"}}) {
    r = run(args);
    EXPECT_EQ(r.code, 2) << args[0];
    EXPECT_NE(r.err.find(what + " is needed, got ''"), std::string::npos) << r.err;
    EXPECT_EQ(r.out, "") << args[0];
  }
  // An export refused leaves no folder it made behind.
  r = run({"export", "999", "--csv", dir_.file("newdir/sub/deep")});
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(std::filesystem::exists(dir_.file("newdir"))) << r.err;
  r = run({"compensate", "1", "--start", "50"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("start 50 is not a measured position (the measured range is 0 to 100)"), std::string::npos)
      << r.err;
  r = run({"analyze", "linear", "1", "--standard", "iso230-2:1988"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("unknown standard 'iso230-2:1988' (one of: iso230-2:2014"), std::string::npos) << r.err;
}

// The report of an imported run: written whole with -o, its verdicts on stdout, one JSON
// document with --json, refusals of what it cannot write.
TEST_F(CliTest, ReportOfALinearRun) {
  ASSERT_EQ(run({"import", "linear", data("linear_deviation.csv"), "--axis", "X"}).code, 0);
  const std::string html = dir_.file("r.html");
  auto r = run({"report", "1", "-o", html, "--tolerance", "E=4"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("report written to " + html), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  E 5.00 µm (tolerance 4.00): FAIL"), std::string::npos) << r.out;
  std::stringstream written;
  written << std::ifstream(html).rdbuf();
  EXPECT_NE(written.str().find("imported"), std::string::npos);
  EXPECT_TRUE(written.str().ends_with("</html>\n"));
  r = run({"report", "1", "--json", "--tolerance", "E=6"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["figures"][0]["symbol"], "E");
  EXPECT_TRUE(r.json()["figures"][0]["passed"].get<bool>());
  r = run({"report", "1", "-o", dir_.file("r.txt")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("a report is written as .html or .pdf"), std::string::npos) << r.err;
  r = run({"report", "1", "--tolerance", "E"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--tolerance 'E': give a figure and its largest passing value"), std::string::npos) << r.err;
  r = run({"report", "1", "--after", "1", "-o", dir_.file("self.html")});  // a report compares two runs
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("run 1 compared with itself"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(dir_.file("self.html")));
  r = run({"report", "1", "--tolerance", "E=inf"});  // no tolerance at all is none, not one that always passes
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--tolerance 'E=inf': give a figure"), std::string::npos) << r.err;
}

TEST_F(CliTest, AirIndexPrintsTheNistValue) {
  auto r = run({"air-index", "--model", "edlen", "--temp-c", "20", "--pressure-pa", "101325", "--humidity-pct", "50",
                "--wavelength-nm", "633", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NEAR(r.json()["n"].get<double>(), 1.000271374, 1e-9);
  r = run({"air-index", "--model", "ciddor", "--temp-c", "20", "--pressure-pa", "101325", "--humidity-pct", "50"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NEAR(std::stod(r.out), 1.00027137, 2e-8);
  r = run({"air-index", "--model", "guess", "--temp-c", "20", "--pressure-pa", "101325", "--humidity-pct", "50"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("edlen or ciddor"), std::string::npos) << r.err;
}

// Imported deviations (2 targets x 2 cycles each way), ISO 230-2 values worked by hand:
// up 0 mm {1,2}, 100 mm {5,5}; down 0 mm {0,0}, 100 mm {2,4}.
TEST_F(CliTest, ImportThenAnalyzeGivesTheHandComputedIso230Values) {
  auto r = run({"import", "linear", data("linear_deviation.csv"), "--axis", "X", "--name", "vendor export", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.json()["warnings"].empty());  // its times are in order
  const int id = r.json()["run_id"].get<int>();
  r = run({"analyze", "iso230-2", std::to_string(id), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = r.json();
  EXPECT_DOUBLE_EQ(j["B_um"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(j["B_mean_um"].get<double>(), 1.75);
  EXPECT_DOUBLE_EQ(j["E_up_um"].get<double>(), 3.5);
  EXPECT_DOUBLE_EQ(j["E_down_um"].get<double>(), 3.0);
  EXPECT_DOUBLE_EQ(j["E_um"].get<double>(), 5.0);
  EXPECT_DOUBLE_EQ(j["M_um"].get<double>(), 3.25);
  // s up at 0 mm = 0.7071, at 100 mm 0; s down 0 and 1.4142: R_up = 4 * 0.7071, R_down = 4 * 1.4142.
  EXPECT_NEAR(j["R_up_um"].get<double>(), 4.0 * std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(j["R_down_um"].get<double>(), 4.0 * std::sqrt(2.0), 1e-12);
  for (const char* key : {"R_um", "A_up_um", "A_down_um", "A_um"}) EXPECT_TRUE(j[key].is_number()) << key;
  ASSERT_EQ(j["positions"].size(), 2u);
  EXPECT_DOUBLE_EQ(j["positions"][1]["mean_down_um"].get<double>(), 3.0);
  EXPECT_DOUBLE_EQ(j["positions"][1]["B_i_um"].get<double>(), 2.0);
  EXPECT_FALSE(j["warnings"].empty());  // 2 cycles < 5

  r = run({"runs", "--json"});
  ASSERT_EQ(r.code, 0);
  ASSERT_EQ(r.json()["runs"].size(), 1u);
  EXPECT_EQ(r.json()["runs"][0]["name"], "vendor export");
  EXPECT_EQ(r.json()["runs"][0]["id"], id);
  r = run({"show", std::to_string(id), "--json"});
  ASSERT_EQ(r.code, 0);
  EXPECT_EQ(r.json()["channels"][0], "spindle_temp_c");
  EXPECT_EQ(r.json()["target_values"].size(), 8u);
}

// A vendor's runs joined into one file, each cycle's clock from zero: imported as given, the
// row named on stderr and in the JSON's warnings, stdout one JSON document; the diagnosis of the
// run says it again.
TEST_F(CliTest, ImportedTimesThatRestartPerCycleAreWarnedAbout) {
  std::ofstream(dir_.file("restarted.csv")) << "target_mm,direction,cycle,deviation_um,time_s\n"
                                               "0,+,1,1.0,0\n100,+,1,2.0,10\n100,-,1,2.5,20\n0,-,1,1.5,30\n"
                                               "0,+,2,1.1,0\n100,+,2,2.1,10\n100,-,2,2.4,20\n0,-,2,1.4,30\n";
  auto r = run({"import", "linear", dir_.file("restarted.csv"), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = r.json();
  ASSERT_EQ(j["warnings"].size(), 1u);
  const std::string expected =
      "restarted.csv:6: column 'time_s': the pass of cycle 2, direction + begins at 0.000 s, the instant the pass of "
      "cycle 1, direction + begins (line 2)";
  EXPECT_NE(j["warnings"][0].get<std::string>().find(expected), std::string::npos) << j;
  EXPECT_NE(r.err.find("warning: "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(expected), std::string::npos) << r.err;
  r = run({"show", std::to_string(j["run_id"].get<int>()), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["target_values"].size(), 8u);
  // Said again where the run's times are used.
  r = run({"diagnose", std::to_string(j["run_id"].get<int>()), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto warnings = r.json()["warnings"].dump();
  EXPECT_NE(warnings.find("run 1 was imported with a warning: "), std::string::npos) << warnings;
  EXPECT_NE(warnings.find(expected), std::string::npos) << warnings;
}

TEST_F(CliTest, AMalformedCsvFailsWithItsLineAndLeavesTheDatabaseUnchanged) {
  auto r = run({"import", "linear", data("linear_bad_row.csv")});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("linear_bad_row.csv:4"), std::string::npos) << r.err;
  EXPECT_TRUE(r.out.empty());
  // The store the import would have created is not left behind, empty; nor by a failed import
  // of another kind.
  EXPECT_FALSE(std::filesystem::exists(db_));
  const std::string empty = dir_.file("empty.csv");
  std::ofstream(empty).close();
  for (const std::vector<std::string>& import :
       {std::vector<std::string>{"import", "circle", empty, "--radius-mm", "100"},
        std::vector<std::string>{"import", "thermal", empty, "--target", "drift_um"},
        std::vector<std::string>{"import", "campaign", empty}}) {
    r = run(import);
    EXPECT_EQ(r.code, 2) << import[1];
    EXPECT_NE(r.err.find("empty.csv: empty file, expected a header line"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(db_)) << import[1];
  }
  // Into a store that holds runs, a failed import adds nothing and the store stays.
  ASSERT_EQ(run({"import", "linear", data("linear_deviation.csv")}).code, 0);
  EXPECT_EQ(run({"import", "linear", data("linear_bad_row.csv")}).code, 2);
  // An axis in lower case is the axis (as a circle's plane is).
  r = run({"import", "linear", data("linear_deviation.csv"), "--axis", "y", "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(run({"show", std::to_string(r.json()["run_ids"][0].get<int>()), "--json"}).json()["axis"], "Y");
  EXPECT_EQ(run({"delete", std::to_string(r.json()["run_ids"][0].get<int>()), "--yes"}).code, 0);
  // Names that head tables: one line, not empty, not a page long; refused before anything is stored.
  for (const auto& [option, value, why] : std::vector<std::tuple<std::string, std::string, std::string>>{
           {"--name", "two\nlines", "a run's name is one line of text: character 4 is 0x0A, a control character"},
           {"--name", std::string(300, 'n'), "a run's name is 300 bytes long: at most 256"},
           {"--machine", "", "a name is needed, got ''"},
           {"--name", "", "a name is needed, got ''"}}) {
    r = run({"import", "linear", data("linear_deviation.csv"), option, value});
    EXPECT_EQ(r.code, 2) << option;
    EXPECT_NE(r.err.find(why), std::string::npos) << r.err;
  }
  r = run({"runs", "--json"});
  EXPECT_EQ(r.json()["runs"].size(), 1u);
  r = run({"analyze", "iso230-2", "42"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("run 42 does not exist"), std::string::npos) << r.err;
  r = run({"import", "linear", "/nonexistent.csv"});
  EXPECT_EQ(r.code, 2);
  r = run({"frobnicate"});
  EXPECT_EQ(r.code, 2);
}

// The same file imported again is imported (on purpose, under another name or machine, it may
// be wanted) and told: the runs that hold its bytes already and how to remove the new copy. The
// file's SHA-256 is stored with the run; a file of the same name with other bytes is not told,
// nor one whose earlier copy was deleted. Every kind of import.
TEST_F(CliTest, AFileImportedAgainIsToldWithTheRunsThatHoldIt) {
  const std::string csv = data("linear_deviation.csv");
  ASSERT_EQ(run({"import", "linear", csv, "--name", "first"}).code, 0);
  auto r = run({"import", "linear", csv, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const std::string told =
      "linear_deviation.csv: the same file was imported before, as run 1 ('first'): run 2 holds it again (mtcal "
      "delete c2 removes this import)";
  EXPECT_EQ(r.json()["warnings"], nlohmann::json::array({told}));
  EXPECT_NE(r.err.find("warning: " + told), std::string::npos) << r.err;
  const auto sha256 = [&](int run_id) {
    return run({"show", std::to_string(run_id), "--json"}).json()["plan"]["imported_sha256"].get<std::string>();
  };
  // The digest of the bytes imported, as coreutils' sha256sum reads the file.
  EXPECT_EQ(sha256(1), mtcal::testing::commandOutput("sha256sum '" + csv + "'").substr(0, 64));
  EXPECT_EQ(sha256(1), sha256(2));
  // The same name, other bytes: a file of its own.
  std::filesystem::create_directories(dir_.file("other"));
  const std::string renamed = dir_.file("other") + "/linear_deviation.csv";
  std::ifstream original(csv);
  std::stringstream text;
  text << original.rdbuf() << "\n";  // one more blank line
  std::ofstream(renamed) << text.str();
  r = run({"import", "linear", renamed, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.json()["warnings"].empty()) << r.out;
  EXPECT_NE(sha256(3), sha256(1));
  // Its copies deleted, a file is new again.
  ASSERT_EQ(run({"delete", "c1", "--yes"}).code, 0);
  ASSERT_EQ(run({"delete", "c2", "--yes"}).code, 0);
  r = run({"import", "linear", csv, "--json"});
  EXPECT_TRUE(r.json()["warnings"].empty()) << r.out;
  // The other kinds, told alike.
  for (const auto& import : std::vector<std::vector<std::string>>{
           {"import", "circle", MTCAL_EXAMPLES_DIR "/circle/xy_r100_export.csv", "--radius-mm", "100", "--feed-mm-min",
            "1000"},
           {"import", "thermal", MTCAL_EXAMPLES_DIR "/thermal/spindle-warmup-8h.csv"},
           {"import", "est", MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv", "--spacing-mm", "20"}}) {
    SCOPED_TRACE(import[1]);
    auto args = import;
    args.push_back("--json");
    const auto first = run(args);
    ASSERT_EQ(first.code, 0) << first.err;
    EXPECT_TRUE(first.json()["warnings"].empty()) << first.out;
    const auto again = run(args);
    ASSERT_EQ(again.code, 0) << again.err;
    const auto warnings = again.json()["warnings"].dump();
    EXPECT_NE(
        warnings.find(fmt::format("the same file was imported before, as run {}", first.json()["run_id"].get<int>())),
        std::string::npos)
        << warnings;
  }
  // An imported EST run's plan, with the file's name and digest, is read back by its analyses.
  EXPECT_EQ(run({"analyze", "est", "9"}).code, 0);
  // A file of several errors is named by its import: the runs of one campaign.
  const std::string six = MTCAL_EXAMPLES_DIR "/import/x_axis_six_errors.csv";
  const auto first = run({"import", "linear", six, "--json"}).json();
  const auto again = run({"import", "linear", six, "--json"}).json();
  const auto campaign = run({"show", std::to_string(first["run_id"].get<int>()), "--json"}).json()["campaign_id"];
  EXPECT_NE(again["warnings"].dump().find(fmt::format(
                "as runs {} (c{}): runs {} hold it again", fmt::join(first["run_ids"].get<std::vector<int>>(), ", "),
                campaign.get<int>(), fmt::join(again["run_ids"].get<std::vector<int>>(), ", "))),
            std::string::npos)
      << again.dump();
}

// A file of several errors says each run's readings: a column with empty cells has fewer.
TEST_F(CliTest, EachErrorOfAFileIsSaidWithItsOwnReadings) {
  const std::string csv = dir_.file("two_errors.csv");
  std::ofstream(csv) << "target_mm,direction,cycle,EXX_um,EYX_um\n"
                        "0,+,1,1.0,0.1\n100,+,1,5.0,\n0,-,1,0.0,0.2\n100,-,1,2.0,0.3\n"
                        "0,+,2,2.0,0.1\n100,+,2,5.0,0.2\n0,-,2,0.0,\n100,-,2,4.0,0.4\n";
  auto r = run({"import", "linear", csv, "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["readings"], (std::vector<int>{8, 6}));
  r = run({"import", "linear", csv});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("imported run 3: 8 readings of EXX\nimported run 4: 6 readings of EYX\n"), std::string::npos)
      << r.out;
}

// An option wrong whatever the file is refused before the file is read: a pipe with no writer
// is not waited for (the import would block in open() until one came). Should it wait, a
// writer that finds it waiting closes the pipe at once, so that the test fails rather than hangs.
TEST_F(CliTest, AWrongImportOptionIsRefusedBeforeThePipeIsRead) {
  const std::string fifo = dir_.file("nobody.csv");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const auto& [kind, option, value, message] : std::vector<std::array<std::string, 4>>{
           {"circle", "--radius-mm", "2e4", "--radius-mm must be > 0 and at most 10 000 mm (10 m), got 20000"},
           {"thermal", "--interval-s", "0", "--interval-s: must be > 0, got 0"},
           {"linear", "--measures", "EQX",
            "import linear: --measures (the error measured): 'EQX' is not one of the errors of axis X"},
           {"linear", "--units", "furlong", "--units 'furlong': not a unit mtcal knows"}}) {
    SCOPED_TRACE(kind);
    Result r;
    std::atomic<bool> done{false};
    std::atomic<int> rescues{0};
    {
      // Opens the pipe for a reader waiting in open() (succeeds only while one waits; without
      // one it fails at once, ENXIO) and closes it: the reader reads an empty file.
      std::jthread rescuer([&] {
        while (!done) {
          if (const int w = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK); w >= 0) {
            ++rescues;
            ::close(w);
          }
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
      });
      struct Done {
        std::atomic<bool>& done;
        ~Done() { done = true; }  // before the thread is joined, also if run() throws
      } stop_rescuing{done};
      r = run({"import", kind, fifo, option, value});
    }
    EXPECT_EQ(rescues, 0) << "the import waited for the pipe's writer";
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
  }
}

// Read from a pipe (nothing to compare later): imported, not hashed, nothing told.
TEST_F(CliTest, AFileFromAPipeIsImported) {
  const std::string fifo = dir_.file("fifo.csv");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::thread writer([&] { std::ofstream(fifo) << std::ifstream(data("linear_deviation.csv")).rdbuf(); });
  auto r = run({"import", "linear", fifo, "--json"});
  if (r.code != 0) {  // it may not have opened the FIFO: open it, so that the writer is not left waiting
    const int reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
    writer.join();
    ::close(reader);
  } else {
    writer.join();
  }
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.json()["warnings"].empty());
  EXPECT_FALSE(run({"show", "1", "--json"}).json()["plan"].contains("imported_sha256"));
}

// The measured line's setup comes from the command's options (or a manifest's entry): a refusal
// names it in words, not as a plan's key ("key 'measures'", "key 'line_position_mm.Q'").
TEST_F(CliTest, AWrongLineSetupIsRefusedInWords) {
  const std::string csv = data("linear_deviation.csv");
  auto r = run({"import", "linear", csv, "--measures", "EQX"});
  EXPECT_EQ(r.code, 2);
  // Said of the options, before the file is read.
  EXPECT_NE(
      r.err.find(
          "import linear: --measures (the error measured): 'EQX' is not one of the errors of axis X (EXX, EYX, EZX, "
          "EAX, EBX, ECX)"),
      std::string::npos)
      << r.err;
  r = run({"import", "linear", csv, "--line-position-mm", "Q=3"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("import linear: --line-position-mm Q: not an axis (X, Y, Z)"), std::string::npos) << r.err;
  // The compensation's settings without --raw would be ignored: refused.
  r = run({"import", "linear", csv, "--wavelength-nm", "633"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--wavelength-nm requires --raw"), std::string::npos) << r.err;
  // A wavelength the air's index equations do not hold for is the option's fault, said before
  // the file is read (it was blamed on the first row's air columns).
  for (const char* wavelength : {"1e9", "200", "0", "nan"}) {
    r = run({"import", "linear", csv, "--raw", "--wavelength-nm", wavelength});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find(std::string("--wavelength-nm must be a laser's vacuum wavelength from 300 to 1700 nm (where "
                                     "the air's index equations hold), got ") +
                         (std::string(wavelength) == "1e9" ? "1000000000" : wavelength)),
              std::string::npos)
        << r.err;
  }
  r = run({"import", "linear", csv, "--line-position-mm", "Y=1,Y=2"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--line-position-mm gives axis Y twice"), std::string::npos) << r.err;
  // The reflector's offset: the value that is wrong, named.
  for (const auto& [given, why] : std::vector<std::pair<std::string, std::string>>{
           {"1,2,nan", "--reflector-offset-mm takes x,y,z in mm, got '1,2,nan': its z 'nan' is not a finite number"},
           {"0x10,0,0", "--reflector-offset-mm takes x,y,z in mm, got '0x10,0,0': its x '0x10' is not a number"},
           {"0,,45", "--reflector-offset-mm takes x,y,z in mm, got '0,,45': its y '' is not a number"},
           {"0,25,45,", "--reflector-offset-mm takes x,y,z in mm (three numbers), got 4 in '0,25,45,'"}}) {
    r = run({"import", "linear", csv, "--reflector-offset-mm", given});
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find(why), std::string::npos) << r.err;
  }
  r = run({"import", "linear", csv, "--line-position-mm", "Y=1e300"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("import linear: --line-position-mm Y: 1e+300 mm is beyond 100 m of the origin (mm, not um)"),
            std::string::npos)
      << r.err;
  r = run({"import", "linear", csv, "--reflector-offset-mm", "0,15000,0"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("its y is 15000 mm: beyond 10 m of the tool point (mm, not um)"), std::string::npos) << r.err;
  r = run({"import", "linear", dir_.path().string()});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find(dir_.path().string() + ": cannot open file: it is a directory"), std::string::npos) << r.err;
  EXPECT_TRUE(run({"runs", "--json"}).json()["runs"].empty());
}

// A number that is not whole, where a whole one is read, is said to be so (it was "not a number").
TEST_F(CliTest, AFractionWhereAWholeNumberIsReadIsSaidToBeSo) {
  auto r = run({"demo", "--seed", "2.5"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--seed: must be a whole number, got 2.5"), std::string::npos) << r.err;
  // A seed is not negative (it was read as 2^64 - 1).
  r = run({"demo", "--seed", "-1"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--seed: must be from 0 to 9223372036854775807, got -1"), std::string::npos) << r.err;
}

TEST_F(CliTest, DemoRunsAFullCampaignAndMatchesTheSimulatedTruth) {
  auto r = run({"demo", "--time-scale", mtcal::testing::timeScaleArg(400), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = r.json();
  EXPECT_EQ(j["status"], "completed");
  EXPECT_EQ(j["iso230_2"]["targets"], 29);
  EXPECT_EQ(j["iso230_2"]["min_cycles"], 9);
  // Means of 9 approaches with 0.6 um scatter: sigma/3 = 0.2 um RMS expected.
  EXPECT_LT(j["simulation_check"]["rms_um"].get<double>(), 0.35);
  EXPECT_LT(j["simulation_check"]["max_abs_um"].get<double>(), 1.0);
  // The demo machine's backlash is 2.5 um: every B_i is close to -2.5.
  EXPECT_NEAR(j["iso230_2"]["B_mean_um"].get<double>(), -2.5, 0.3);
  r = run({"show", std::to_string(j["run_id"].get<int>())});
  EXPECT_NE(r.out.find("522 targets captured"), std::string::npos) << r.out;
}

TEST_F(CliTest, AnInterruptedRunIsResumedToCompletion) {
  std::atomic<bool> stop{true};  // Ctrl-C right away: the datum is taken, no target
  auto r = run({"demo", "--time-scale", mtcal::testing::timeScaleArg(400), "--json"}, &stop);
  EXPECT_EQ(r.code, 1);
  const auto j = r.json();
  EXPECT_EQ(j["status"], "interrupted");
  const int id = j["run_id"].get<int>();
  r = run({"resume", std::to_string(id), "--time-scale", mtcal::testing::timeScaleArg(400), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["status"], "completed");
  EXPECT_EQ(r.json()["iso230_2"]["min_cycles"], 9);
  r = run({"resume", std::to_string(id)});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("already completed"), std::string::npos) << r.err;
}

TEST_F(CliTest, ATriggeredRunRehearsesTheRealMachineWorkflow) {
  const std::string plan = dir_.file("plan.json");
  std::ofstream(plan) << R"({"start_mm": 100, "end_mm": 200, "step_mm": 50, "repeats": 3})";
  auto r = run({"run", "linear", plan, "--triggered", "--time-scale", mtcal::testing::timeScaleArg(400), "--json"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto j = r.json();
  EXPECT_EQ(j["iso230_2"]["targets"], 3);
  EXPECT_EQ(j["iso230_2"]["min_cycles"], 3);
  EXPECT_LT(j["simulation_check"]["max_abs_um"].get<double>(), 1.5);
}

// Several plans: one campaign on one virtual machine, the optics set up for each; a real
// machine or a triggered run takes one plan at a time.
TEST_F(CliTest, SeveralPlansRunAsOneCampaign) {
  const std::string positioning = dir_.file("exx.json"), pitch = dir_.file("ebx.json");
  std::ofstream(positioning) << R"({"start_mm": 100, "end_mm": 200, "step_mm": 50, "repeats": 2,
                                    "line_position_mm": {"Y": 120}})";
  std::ofstream(pitch) << R"({"measures": "EBX", "start_mm": 100, "end_mm": 200, "step_mm": 50, "repeats": 2})";
  auto r = run({"--json", "run", "linear", positioning, pitch, "--time-scale", mtcal::testing::timeScaleArg(400)});
  ASSERT_EQ(r.code, 0) << r.err;
  // One JSON document for the campaign: its runs in the plans' order.
  ASSERT_EQ(r.json()["runs"].size(), 2u);
  EXPECT_EQ(r.json()["runs"][0]["campaign_id"], r.json()["campaign_id"]);
  EXPECT_EQ(r.json()["runs"][1]["measures"], "EBX");
  r = run({"runs", "--json"});
  const auto runs = r.json()["runs"];
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0]["campaign_id"], runs[1]["campaign_id"]);
  r = run({"show", "2", "--json"});
  EXPECT_EQ(r.json()["plan"]["measures"], "EBX");
  EXPECT_EQ(r.json()["campaign"], "2 plans, from 'linear positioning' to 'linear positioning'");
  r = run({"run", "linear", positioning, pitch, "--triggered"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("one part program at a time"), std::string::npos) << r.err;
}

TEST_F(CliTest, PlanGcodeWritesTheProgram) {
  const std::string plan = dir_.file("plan.json");
  std::ofstream(plan) << R"({"axis": "Y", "start_mm": 0, "end_mm": 100, "step_mm": 25, "repeats": 5})";
  const std::string program = dir_.file("plan.nc");
  auto r = run({"plan", "gcode", plan, "-o", program});
  ASSERT_EQ(r.code, 0) << r.err;
  std::ifstream in(program);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_NE(text.str().find("G1 Y100.0000 (target 5 cycle 1 up)"), std::string::npos);
  std::ofstream(plan) << R"({"axis": "Y", "step_mm": 0})";
  r = run({"plan", "gcode", plan});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("'step_mm'"), std::string::npos) << r.err;
  r = run({"plan", "gcode", std::string(MTCAL_EXAMPLES_DIR) + "/plans/est/x_guideway_two_probe.json"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("an EST plan has no part program yet"), std::string::npos) << r.err;
  r = run({"plan", "gcode", plan, "-o", ""});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("a file name is needed, got ''"), std::string::npos) << r.err;
}

// The contract a new user meets: help for any command, mistakes named in words, the plan's
// kind, the campaign of a run, the machine a seed makes and who measured.
TEST_F(CliTest, HelpAndMistakesSpeakToPeople) {
  auto r = run({"help", "run", "linear"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("Usage: mtcal run linear"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("Global options"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--operator NAME"), std::string::npos) << r.out;
  r = run({"help"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("diagnose"), std::string::npos) << r.out;  // the commands, not help's own options
  EXPECT_EQ(r.out.find("Usage: mtcal help"), std::string::npos) << r.out;
  r = run({"help", "run", "nope"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("'nope' is not a command of mtcal run"), std::string::npos) << r.err;
  // A command that is none, or none given, is said so with the commands there are.
  r = run({"run", "nope"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("'nope' is not a command of mtcal run (commands: linear, ballbar, est, gantry, thermal;"),
            std::string::npos)
      << r.err;
  r = run({"model"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("mtcal model needs a command (commands: import, identify,"), std::string::npos) << r.err;
  r = run({"--json", "bogus"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(nlohmann::json::parse(r.out)["error"].get<std::string>().find("'bogus' is not a command of mtcal ("),
            std::string::npos)
      << r.out;
  // With --json, help and the version are the one document on stdout too, the same words inside.
  const auto text = run({"help", "diagnose"}).out;
  for (const std::vector<std::string>& args : {std::vector<std::string>{"--json", "help", "diagnose"},
                                               std::vector<std::string>{"--json", "diagnose", "--help"}}) {
    r = run(args);
    ASSERT_EQ(r.code, 0) << r.err;
    const auto document = nlohmann::json::parse(r.out);
    EXPECT_EQ(document["schema_version"], 1);
    EXPECT_NE(document["help"].get<std::string>().find("Usage: mtcal diagnose"), std::string::npos) << r.out;
  }
  EXPECT_EQ(nlohmann::json::parse(run({"--json", "help", "diagnose"}).out)["help"], text);
  r = run({"--json", "--version"});
  EXPECT_EQ(nlohmann::json::parse(r.out)["version"], services::kVersion) << r.out;

  const std::string circle = std::string(MTCAL_EXAMPLES_DIR) + "/circle/xy_r100_export.csv";
  r = run({"import", "circle", circle, "--radius-mm", "-5"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--radius-mm: must be > 0, got -5"), std::string::npos) << r.err;
  EXPECT_LT(r.err.size(), 140u) << r.err;  // not the largest double
  r = run({"import", "circle", circle, "--radius-mm", "100", "--plane", "XZ"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("give ZX"), std::string::npos) << r.err;

  r = run({"run", "linear", std::string(MTCAL_EXAMPLES_DIR) + "/plans/ballbar/circle_xy_100.json"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("this is a circle plan: run it with `mtcal run ballbar`"), std::string::npos) << r.err;
  // Tables for the virtual CNC: a format without a table, two tables for one axis.
  const std::string plan = std::string(MTCAL_EXAMPLES_DIR) + "/plans/x_axis_iso230-2.json";
  r = run({"run", "linear", plan, "--controller", "fanuc"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--controller names the format of --compensation tables: none is given"), std::string::npos)
      << r.err;
  r = run({"run", "linear", plan, "--compensation", "a.comp", "--compensation", "X=b.comp"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--compensation: two tables for axis X (a.comp and b.comp)"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(db_));
  r = run({"run", "ballbar", std::string(MTCAL_EXAMPLES_DIR) + "/plans/x_axis_iso230-2.json"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("this is a linear plan: run it with `mtcal run linear`"), std::string::npos) << r.err;
  // A plan beyond the machine's travel is refused before anything moves: nothing stored.
  const std::string far = dir_.file("far.json");
  std::ofstream(far) << R"({"axis": "X", "start_mm": 50, "end_mm": 900, "step_mm": 50, "repeats": 2})";
  r = run({"run", "linear", far, "--time-scale", "3000"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("outside the machine's travel"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(db_));  // nothing stored: no archive made
  // Far beyond, in a few digits.
  std::ofstream(far) << R"({"axis": "X", "start_mm": 50, "end_mm": 1e300, "step_mm": 1e299, "repeats": 2})";
  r = run({"run", "linear", far, "--time-scale", "3000"});
  EXPECT_EQ(r.code, 2);
  EXPECT_LT(r.err.size(), 300u) << r.err;
  // So is a datum beyond it, taken before the first target (the demo machine's X: 0..700 mm).
  std::ofstream(far) << R"({"axis": "X", "start_mm": 50, "end_mm": 300, "step_mm": 50, "repeats": 2,
                            "datum_mm": 5000})";
  r = run({"run", "linear", far, "--time-scale", "3000"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(
      r.err.find(
          "'linear positioning' (datum_mm, approached from overrun_mm below it) needs X at 4995.000 mm, outside the "
          "machine's travel [0, 700] mm"),
      std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(db_));
  r = run({"--json", "runs"});
  EXPECT_EQ(r.code, 2);
  // --json: the one document on stdout is the error; a read command on a mistyped --db creates nothing.
  EXPECT_EQ(r.json()["exit_code"], 2);
  EXPECT_NE(r.json()["error"].get<std::string>().find("no store"), std::string::npos) << r.out;
  EXPECT_NE(r.err.find("no store '" + db_ + "'"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(db_));
  r = run({"est", far, "--spacing-mm", "0"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("--spacing-mm: must be > 0, got 0"), std::string::npos) << r.err;
  // An imported EST file's spacing that is not its step: said as the option and the file's step.
  const std::string probes = MTCAL_EXAMPLES_DIR "/est/guideway_400mm.csv";
  r = run({"import", "est", probes, "--spacing-mm", "25"});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find(probes + ": --spacing-mm 25 (the file steps by 20 mm): three probes need a spacing of one step"),
            std::string::npos)
      << r.err;
  const std::string typo = dir_.file("typo.json");
  std::ofstream(typo) << R"({"type": "circle", "radius_mm": 100, "fead_mm_per_min": 500})";
  r = run({"run", "ballbar", typo});
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("key 'fead_mm_per_min': unknown key; did you mean 'feed_mm_per_min'?"), std::string::npos)
      << r.err;
}

TEST_F(CliTest, ARunNamesItsCampaignItsOperatorAndItsSeededMachine) {
  const std::string machine = std::string(MTCAL_EXAMPLES_DIR) + "/machines/vmc-850.json";
  const std::string plan = std::string(MTCAL_EXAMPLES_DIR) + "/plans/est/x_guideway_two_probe.json";
  auto r = run({"--operator", "C. Tester", "run", "est", plan, "--machine-config", machine, "--seed", "7",
                "--time-scale", mtcal::testing::timeScaleArg(3000)});
  ASSERT_EQ(r.code, 0) << r.err;
  r = run({"--json", "runs"});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto runs = r.json()["runs"];
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0]["operator"], "C. Tester");
  EXPECT_EQ(runs[0]["measured"], 21);
  EXPECT_EQ(runs[0]["measured_unit"], "probe steps");
  EXPECT_NE(runs[0]["machine"].get<std::string>().find("(seed 7)"), std::string::npos)
      << runs[0].dump();  // not the file's 42
  r = run({"runs"});
  EXPECT_NE(r.out.find("c1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("21 probe steps"), std::string::npos) << r.out;
  r = run({"show", "1"});
  EXPECT_NE(r.out.find("campaign c1"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("operator C. Tester"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("instrument: probes"), std::string::npos) << r.out;

  r = run({"--json", "run", "linear", std::string(MTCAL_EXAMPLES_DIR) + "/plans/x_axis_iso230-2.json", "--time-scale",
           mtcal::testing::timeScaleArg(3000)});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.json()["campaign_id"], 2);
}

}  // namespace
}  // namespace mtcal::app
