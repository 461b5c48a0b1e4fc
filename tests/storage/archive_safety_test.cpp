// An archive several processes use at once, a run whose process is killed, an archive nobody
// may write: each with real processes (fork), real permissions and real SQLite.

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../support/child_process.h"
#include "../support/temp_dir.h"
#include "mtcal/error.h"
#include "mtcal/storage/schema.h"
#include "mtcal/storage/store.h"

namespace mtcal::storage {
namespace {

using mtcal::testing::ChildUser;
using mtcal::testing::inChildProcess;

Id newRun(Store& s, const std::string& machine = "m") {
  NewRun r;
  r.campaign_id = s.addCampaign(s.ensureMachine(machine, "", "{}"), "c");
  r.name = "run";
  r.axis = "X";
  r.software_version = "test";
  return s.addRun(r);
}

std::string integrity(Store& s) {
  Statement st(s.database(), "PRAGMA integrity_check");
  st.step();
  return st.getText(0);
}

bool hasEvent(Store& s, Id run, const std::string& text) {
  for (const auto& e : s.events(run)) {
    if (e.message.find(text) != std::string::npos) return true;
  }
  return false;
}

TEST(ArchiveSafety, ProcessesCreatingOneNewArchiveAtOnceAllSucceed) {
  const mtcal::testing::TempDir dir;
  constexpr int kTrials = 3, kProcesses = 4;
  for (int trial = 0; trial < kTrials; ++trial) {
    const std::string path = dir.file("new" + std::to_string(trial) + ".sqlite");
    // Every child blocks on the same pipe; closing it releases them at once.
    int go[2];
    ASSERT_EQ(::pipe(go), 0);
    std::vector<pid_t> children;
    for (int k = 0; k < kProcesses; ++k) {
      const pid_t pid = ::fork();
      ASSERT_GE(pid, 0);
      if (pid == 0) {
        ::close(go[1]);
        char c;
        (void)::read(go[0], &c, 1);
        try {
          Store s(path);
          newRun(s, "machine " + std::to_string(k));
        } catch (const std::exception& e) {
          ::fprintf(stderr, "process %d: %s\n", k, e.what());
          ::_exit(1);
        }
        ::_exit(0);
      }
      children.push_back(pid);
    }
    ::close(go[0]);
    ::close(go[1]);
    for (const pid_t pid : children) {
      int status = 0;
      ::waitpid(pid, &status, 0);
      EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "trial " << trial;
    }
    Store s(path);
    EXPECT_EQ(s.listRuns().size(), static_cast<std::size_t>(kProcesses)) << "trial " << trial;
    EXPECT_EQ(integrity(s), "ok");
    Statement v(s.database(), "PRAGMA user_version");
    v.step();
    EXPECT_EQ(v.getInt(0), currentSchemaVersion());
  }
}

TEST(ArchiveSafety, WritersOnOneArchiveAtOnceLoseNothing) {
  const mtcal::testing::TempDir dir;
  const std::string path = dir.file("shared.sqlite");
  { Store s(path); }
  constexpr int kProcesses = 4, kRunsEach = 25;
  std::vector<pid_t> children;
  for (int k = 0; k < kProcesses; ++k) {
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      try {
        Store s(path);
        for (int r = 0; r < kRunsEach; ++r) {
          NewRun run;
          run.campaign_id = s.addCampaign(s.ensureMachine("station " + std::to_string(k), "", "{}"), "c");
          run.name = "run " + std::to_string(r);
          run.status = run_status::kImported;
          run.source = "imported";
          run.software_version = "test";
          std::vector<TargetRecord> targets(20);
          for (int t = 0; t < 20; ++t) {
            targets[t].seq = t;
            targets[t].target_mm = 10.0 * t;
            targets[t].direction = 1;
            targets[t].cycle = 1;
            targets[t].measured_mm = 10.0 * t;
            targets[t].deviation_um = 0.1 * t;
          }
          s.importRun(run, targets, {}, {});
        }
      } catch (const std::exception& e) {
        ::fprintf(stderr, "writer %d: %s\n", k, e.what());
        ::_exit(1);
      }
      ::_exit(0);
    }
    children.push_back(pid);
  }
  for (const pid_t pid : children) {
    int status = 0;
    ::waitpid(pid, &status, 0);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  }
  Store s(path);
  EXPECT_EQ(s.listRuns().size(), static_cast<std::size_t>(kProcesses * kRunsEach));
  Statement targets(s.database(), "SELECT COUNT(*) FROM targets");
  targets.step();
  EXPECT_EQ(targets.getInt(0), kProcesses * kRunsEach * 20);
  EXPECT_TRUE(s.check().empty());
}

TEST(ArchiveSafety, ARunWhoseProcessWasKilledReadsInterruptedAndIsResumable) {
  const mtcal::testing::TempDir dir;
  const std::string path = dir.file("a.sqlite");
  { Store s(path); }
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::close(ready[0]);
    Store s(path);
    const Id run = newRun(s);
    (void)::write(ready[1], &run, sizeof run);
    for (;;) ::pause();  // recording, until killed
  }
  ::close(ready[1]);
  Id run = 0;
  ASSERT_EQ(::read(ready[0], &run, sizeof run), static_cast<ssize_t>(sizeof run));
  ::close(ready[0]);
  Store s(path);
  {
    const auto live = s.run(run);
    EXPECT_EQ(live.status, run_status::kRunning);
    EXPECT_FALSE(live.stale);
    ASSERT_TRUE(live.owner);
    EXPECT_EQ(live.owner->pid, pid);
    try {
      s.claimRun(run);
      ADD_FAILURE() << "a live run was taken over";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("is being recorded by process " + std::to_string(pid)), std::string::npos)
          << e.what();
    }
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, nullptr, 0);
  const auto dead = s.run(run);
  EXPECT_EQ(dead.status, run_status::kInterrupted);
  EXPECT_TRUE(dead.stale);
  const auto resumed = s.claimRun(run);
  EXPECT_EQ(resumed.status, run_status::kRunning);
  EXPECT_FALSE(resumed.stale);
  EXPECT_EQ(resumed.owner->pid, ::getpid());
  EXPECT_TRUE(hasEvent(s, run, "interrupted: process " + std::to_string(pid)));
  EXPECT_TRUE(hasEvent(s, run, "resumed by process " + std::to_string(::getpid())));
  s.setRunStatus(run, run_status::kCompleted);
  EXPECT_THROW(s.claimRun(run), InputError);  // completed: nothing to resume
  EXPECT_EQ(integrity(s), "ok");
}

TEST(ArchiveSafety, AReadOnlyArchiveIsReadAndNeverWritten) {
  const mtcal::testing::TempDir dir;
  const auto folder = dir.path() / "archive";
  std::filesystem::create_directories(folder);
  const std::string path = (folder / "ro.sqlite").string();
  Id run = 0;
  {
    Store s(path);
    run = newRun(s);
    s.setRunStatus(run, run_status::kCompleted);
    s.addResult(run, "iso230-2", "1", "{}", R"({"E_um": 1.5})");
  }
  ASSERT_EQ(::chmod(path.c_str(), 0444), 0);
  ASSERT_EQ(::chmod(folder.c_str(), 0555), 0);
  // As a quality engineer without write permission on the folder: no journal can be created.
  std::string message = inChildProcess(
      [&]() -> std::string {
        Store s(path, Open::kExisting);
        if (!s.readOnly()) return "the archive was opened for writing";
        if (s.listRuns().size() != 1) return "runs not listed";
        if (s.results(run).size() != 1) return "results not read";
        try {
          newRun(s);
          return "a run was written";
        } catch (const StorageError& e) {
          const std::string what = e.what();
          if (what.find("is read-only") == std::string::npos) return "unclear error: " + what;
        }
        return {};
      },
      ChildUser::kUnprivileged);
  EXPECT_EQ(message, "");
  std::vector<std::string> files;
  for (const auto& f : std::filesystem::directory_iterator(folder)) files.push_back(f.path().filename().string());
  EXPECT_EQ(files, std::vector<std::string>{"ro.sqlite"});  // no -wal, no -shm left beside it
  // A folder everyone may write, the file only its owner's: the reader leaves no journal
  // behind (one it owned would lock the owner out of his own archive).
  ASSERT_EQ(::chmod(folder.c_str(), 0777), 0);
  ASSERT_EQ(::chmod(path.c_str(), 0644), 0);
  message = inChildProcess(
      [&]() -> std::string {
        Store s(path, Open::kExisting);
        if (!s.readOnly()) return "the archive was opened for writing";
        return s.listRuns().size() == 1 ? std::string() : "runs not listed";
      },
      ChildUser::kUnprivileged);
  EXPECT_EQ(message, "");
  files.clear();
  for (const auto& f : std::filesystem::directory_iterator(folder)) files.push_back(f.path().filename().string());
  EXPECT_EQ(files, std::vector<std::string>{"ro.sqlite"});
  {
    Store owner(path);
    EXPECT_FALSE(owner.readOnly());
    owner.logEvent(run, "info", "the owner still writes");
  }
  ASSERT_EQ(::chmod(folder.c_str(), 0755), 0);
  // Read-only by request, with a writable folder: still never written.
  Store s(path, Open::kReadOnly);
  EXPECT_TRUE(s.readOnly());
  EXPECT_THROW(s.setRunStatus(run, run_status::kFailed), StorageError);
  EXPECT_EQ(s.run(run).status, run_status::kCompleted);
}

TEST(ArchiveSafety, AMissingArchiveIsAnErrorWhenNotCreating) {
  const mtcal::testing::TempDir dir;
  const std::string path = dir.file("typo.sqlite");
  try {
    Store s(path, Open::kExisting);
    ADD_FAILURE() << "opened a missing archive";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("no store '" + path + "'"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(ArchiveSafety, AnotherSqliteFileIsNeverTakenForAnArchive) {
  const mtcal::testing::TempDir dir;
  const std::string other = dir.file("customers.sqlite"), empty = dir.file("empty.sqlite");
  {
    Database db(other);
    db.exec("PRAGMA journal_mode = DELETE");  // another program's file, as such files usually are
    db.exec("CREATE TABLE customers (name TEXT)");
  }
  const auto bytes = [](const std::string& path) {
    std::stringstream s;
    s << std::ifstream(path, std::ios::binary).rdbuf();
    return s.str();
  };
  const std::string before = bytes(other);
  for (const auto open : {Open::kExisting, Open::kCreate}) {
    try {
      Store s(other, open);
      ADD_FAILURE() << "opened another program's database as an archive";
    } catch (const InputError& e) {  // a wrong --db: the input's fault (exit 2), not the storage's
      EXPECT_NE(std::string(e.what()).find("is an SQLite database but not an mtcal store (its tables: customers)"),
                std::string::npos)
          << e.what();
    }
  }
  EXPECT_EQ(bytes(other), before);  // not a byte written (not even the switch to WAL)
  EXPECT_FALSE(std::filesystem::exists(other + "-wal"));
  {
    Database db(other);
    Statement st(db, "SELECT count(*) FROM sqlite_master");
    st.step();
    EXPECT_EQ(st.getInt(0), 1);
  }
  // An empty file: not an archive to read; a new one where runs are recorded.
  std::ofstream{empty};
  EXPECT_THROW(Store(empty, Open::kExisting), InputError);
  EXPECT_EQ(std::filesystem::file_size(empty), 0u);
  Store created(empty, Open::kCreate);
  EXPECT_TRUE(created.listRuns().empty());
}

TEST(ArchiveSafety, TheSameAnalysisIsStoredOnceAndAnotherIsANewVersion) {
  const mtcal::testing::TempDir dir;
  Store s(dir.file("r.sqlite"));
  const Id run = newRun(s);
  const Id first = s.addResult(run, "iso230-2", "1", "{}", R"({"E_um": 1.5})");
  EXPECT_EQ(s.addResult(run, "iso230-2", "1", "{}", R"({"E_um": 1.5})"), first);
  const Id changed = s.addResult(run, "iso230-2", "1", "{}", R"({"E_um": 1.6})");  // more data, another output
  EXPECT_NE(changed, first);
  EXPECT_NE(s.addResult(run, "iso230-2", "2", "{}", R"({"E_um": 1.5})"), first);  // another version
  EXPECT_EQ(s.results(run).size(), 3u);
}

}  // namespace
}  // namespace mtcal::storage
