#pragma once
// A disk that fills up (or fails), without filling one: an SQLite VFS over the platform's
// whose writes fail with SQLITE_FULL (or an I/O error) once a budget of bytes is spent (SQLite's documented VFS
// interface, https://sqlite.org/vfs.html). While it lives it is the default VFS, so every connection the code under
// test opens (the writer, a checkpointer, the heartbeat) writes through it; the code under test is not changed.

#include <sqlite3.h>

#include <atomic>
#include <cstdint>
#include <cstring>
#include <limits>

namespace mtcal::testing {

class FullDiskVfs {
 public:
  FullDiskVfs() {
    real_ = sqlite3_vfs_find(nullptr);
    vfs_ = *real_;
    vfs_.zName = "mtcal-full-disk";
    vfs_.szOsFile = static_cast<int>(sizeof(File)) + real_->szOsFile;
    vfs_.xOpen = &open;
    vfs_.pAppData = this;
    sqlite3_vfs_register(&vfs_, 1);
  }
  ~FullDiskVfs() {
    sqlite3_vfs_unregister(&vfs_);
    sqlite3_vfs_register(real_, 1);
  }
  FullDiskVfs(const FullDiskVfs&) = delete;
  FullDiskVfs& operator=(const FullDiskVfs&) = delete;

  /// Bytes that may still be written; the disk is full once they are spent.
  void setFree(std::int64_t bytes) { free_ = bytes; }
  /// What a write beyond the budget fails with: SQLITE_FULL (the default), or an I/O error
  /// (SQLITE_IOERR_WRITE: a failing disk, a pulled USB stick).
  void setFailure(int code) { failure_ = code; }
  void setUnlimited() { free_ = std::numeric_limits<std::int64_t>::max(); }
  /// Writes refused so far.
  int refused() const { return refused_; }

 private:
  struct File {
    sqlite3_file base;
    FullDiskVfs* owner;
    sqlite3_file* real;  // the platform's file, stored right after this struct
  };
  static sqlite3_file* real(sqlite3_file* f) { return reinterpret_cast<File*>(f)->real; }

  static int open(sqlite3_vfs* vfs, sqlite3_filename name, sqlite3_file* file, int flags, int* out_flags) {
    auto* self = static_cast<FullDiskVfs*>(vfs->pAppData);
    auto* f = reinterpret_cast<File*>(file);
    f->owner = self;
    f->real = reinterpret_cast<sqlite3_file*>(f + 1);
    const int rc = self->real_->xOpen(self->real_, name, f->real, flags, out_flags);
    if (rc != SQLITE_OK) {
      f->base.pMethods = nullptr;
      return rc;
    }
    self->io_ = *f->real->pMethods;
    self->io_.xClose = [](sqlite3_file* x) { return real(x)->pMethods->xClose(real(x)); };
    self->io_.xRead = [](sqlite3_file* x, void* b, int n, sqlite3_int64 o) {
      return real(x)->pMethods->xRead(real(x), b, n, o);
    };
    self->io_.xWrite = [](sqlite3_file* x, const void* b, int n, sqlite3_int64 o) {
      auto* owner = reinterpret_cast<File*>(x)->owner;
      if (owner->free_.fetch_sub(n) < n) {
        owner->free_ = 0;
        ++owner->refused_;
        return owner->failure_.load();
      }
      return real(x)->pMethods->xWrite(real(x), b, n, o);
    };
    self->io_.xTruncate = [](sqlite3_file* x, sqlite3_int64 s) { return real(x)->pMethods->xTruncate(real(x), s); };
    self->io_.xSync = [](sqlite3_file* x, int fl) { return real(x)->pMethods->xSync(real(x), fl); };
    self->io_.xFileSize = [](sqlite3_file* x, sqlite3_int64* s) { return real(x)->pMethods->xFileSize(real(x), s); };
    self->io_.xLock = [](sqlite3_file* x, int l) { return real(x)->pMethods->xLock(real(x), l); };
    self->io_.xUnlock = [](sqlite3_file* x, int l) { return real(x)->pMethods->xUnlock(real(x), l); };
    self->io_.xCheckReservedLock = [](sqlite3_file* x, int* r) {
      return real(x)->pMethods->xCheckReservedLock(real(x), r);
    };
    self->io_.xFileControl = [](sqlite3_file* x, int op, void* a) {
      return real(x)->pMethods->xFileControl(real(x), op, a);
    };
    self->io_.xSectorSize = [](sqlite3_file* x) { return real(x)->pMethods->xSectorSize(real(x)); };
    self->io_.xDeviceCharacteristics = [](sqlite3_file* x) {
      return real(x)->pMethods->xDeviceCharacteristics(real(x));
    };
    if (self->io_.iVersion >= 2) {
      self->io_.xShmMap = [](sqlite3_file* x, int pg, int sz, int ext, void volatile** p) {
        return real(x)->pMethods->xShmMap(real(x), pg, sz, ext, p);
      };
      self->io_.xShmLock = [](sqlite3_file* x, int o, int n, int fl) {
        return real(x)->pMethods->xShmLock(real(x), o, n, fl);
      };
      self->io_.xShmBarrier = [](sqlite3_file* x) { real(x)->pMethods->xShmBarrier(real(x)); };
      self->io_.xShmUnmap = [](sqlite3_file* x, int d) { return real(x)->pMethods->xShmUnmap(real(x), d); };
    }
    if (self->io_.iVersion >= 3) {
      self->io_.xFetch = [](sqlite3_file* x, sqlite3_int64 o, int n, void** p) {
        return real(x)->pMethods->xFetch(real(x), o, n, p);
      };
      self->io_.xUnfetch = [](sqlite3_file* x, sqlite3_int64 o, void* p) {
        return real(x)->pMethods->xUnfetch(real(x), o, p);
      };
    }
    f->base.pMethods = &self->io_;
    return SQLITE_OK;
  }

  sqlite3_vfs* real_ = nullptr;
  sqlite3_vfs vfs_{};
  sqlite3_io_methods io_{};
  std::atomic<std::int64_t> free_{std::numeric_limits<std::int64_t>::max()};
  std::atomic<int> refused_{0};
  std::atomic<int> failure_{SQLITE_FULL};
};

}  // namespace mtcal::testing
