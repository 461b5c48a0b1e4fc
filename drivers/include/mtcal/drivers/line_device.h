#pragma once
// An instrument that speaks a line protocol over any Transport: one reply line per command,
// unsolicited stream lines while it streams (the probe box, the temperature logger). The
// shared part of their drivers: commands with a deadline, the reader thread that hands
// stream lines to the driver and replies to the control thread, its error, garbled lines.
//
// Thread-safety: commands from one control thread; while streaming, the reader thread only
// calls onStreamLine (the driver's sink) and hands command replies to the control thread.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>

#include "mtcal/drivers/instrument.h"
#include "mtcal/drivers/line_decoder.h"
#include "mtcal/drivers/reader_thread.h"
#include "mtcal/drivers/transport.h"

namespace mtcal::drivers {

struct LineTimeouts {
  std::chrono::milliseconds command{1000};  ///< write + reply of one command
  std::chrono::milliseconds read{100};      ///< one transport read in the reader loop
  std::chrono::milliseconds stall{2000};    ///< no stream line for this long is an error
};

class LineDevice : public Instrument {
 public:
  ~LineDevice() override;
  void poll() override;
  /// Stream lines delivered, lost (sequence gaps and garbled lines), overlong lines skipped.
  StreamStats stats() const override;

 protected:
  LineDevice(std::unique_ptr<Transport> transport, std::string uri, LineTimeouts timeouts, std::size_t max_line_bytes);

  /// Writes a command (a whole line) and returns the reply line; stream lines that arrive
  /// before it belong to nobody and are skipped. @throws TimeoutError, TransportError, the
  /// reader's error
  std::string transact(const std::string& command);
  /// Starts the reader thread delivering to `sink` (the instrument was told to stream).
  /// `stall`: no stream line for this long is an error (default: the timeouts' stall; longer
  /// for lines that come only when something else happens, a trigger).
  void startReader(const char* thread_name, SampleSink& sink,
                   std::optional<std::chrono::milliseconds> stall = std::nullopt);
  /// One stream line's samples to the sink (reader thread); a gap in `seq` counts as lost lines.
  void deliver(std::uint32_t seq, std::span<const Sample> samples);
  /// Sends `stop_command`, checks its reply, joins the reader and rethrows what either failed with.
  void stopReader(const std::string& stop_command, const std::function<void(const std::string&)>& check_reply);
  bool streaming() const { return streaming_; }

  virtual bool isStreamLine(const std::string& line) const = 0;
  /// One stream line, on the reader thread. A ProtocolError counts the line as garbled and
  /// skips it; anything else stops the stream.
  virtual void onStreamLine(const std::string& line) = 0;

  const std::string& uri() const { return uri_; }
  const LineTimeouts& timeouts() const { return timeouts_; }
  std::uint64_t garbledLines() const { return bad_lines_; }
  std::uint64_t overlongLines() const { return decoder_.overlongLines(); }

 private:
  std::string readLine(std::chrono::steady_clock::time_point deadline, const std::string& command);
  void readerLoop();

  std::unique_ptr<Transport> transport_;
  std::string uri_;
  LineTimeouts timeouts_;
  std::chrono::milliseconds reader_stall_{0};  ///< of the running reader
  LineDecoder decoder_;                        // reader thread while streaming, the control thread otherwise

  std::mutex command_mutex_;
  std::mutex reply_mutex_;  // guards replies_; waited on for a reply or the reader's failure
  std::condition_variable reply_cv_;
  std::deque<std::string> replies_;
  std::atomic<bool> streaming_{false};
  std::atomic<std::uint64_t> bad_lines_{0}, lines_{0}, lost_{0};
  SampleSink* sink_ = nullptr;
  std::optional<std::uint32_t> next_seq_;  // reader thread
  ReaderThread reader_;                    // last: joined before the members its loop uses are destroyed
};

}  // namespace mtcal::drivers
