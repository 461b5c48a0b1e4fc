#pragma once
// One operation at a time on a transport, and no read begun while another operation waits. A
// reader thread takes the transport again as soon as its read returns; a plain mutex lets it (a
// std::mutex is not fair), so a command's write could wait behind read after read for as long
// as the stream runs. Here a write (or any other operation) waits for the read in progress
// only: at most that read's timeout.

#include <condition_variable>
#include <mutex>

namespace mtcal::drivers {

class OperationGate {
 public:
  enum class Kind { kRead, kOther };
  /// The transport's turn for one operation, held while it lives.
  class Turn {
   public:
    Turn(OperationGate& gate, Kind kind) : gate_(gate) { gate_.enter(kind); }
    ~Turn() { gate_.leave(); }
    Turn(const Turn&) = delete;
    Turn& operator=(const Turn&) = delete;

   private:
    OperationGate& gate_;
  };

 private:
  void enter(Kind kind) {
    std::unique_lock lock(mutex_);
    if (kind == Kind::kOther) ++others_waiting_;
    changed_.wait(lock, [&] { return !busy_ && (kind == Kind::kOther || others_waiting_ == 0); });
    if (kind == Kind::kOther) --others_waiting_;
    busy_ = true;
  }
  void leave() {
    {
      std::lock_guard lock(mutex_);
      busy_ = false;
    }
    changed_.notify_all();
  }

  std::mutex mutex_;
  std::condition_variable changed_;
  bool busy_ = false;
  int others_waiting_ = 0;
};

}  // namespace mtcal::drivers
