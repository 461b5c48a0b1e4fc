#pragma once
// The one exception hierarchy of mtcal. Native error codes (libusb, SQLite, errno, Asio)
// are converted into these at the boundary where they occur; nothing above a transport
// or the storage layer ever sees a library-specific code.

#include <stdexcept>
#include <string>

namespace mtcal {

/// Base of every error mtcal throws on purpose.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The link to a device failed or broke (open, claim, I/O error, disconnect).
class TransportError : public Error {
 public:
  using Error::Error;
};

/// A blocking call did not complete within its timeout.
class TimeoutError : public TransportError {
 public:
  using TransportError::TransportError;
};

/// Bytes arrived that do not form a valid message (sync, length, CRC, unknown type).
class ProtocolError : public Error {
 public:
  using Error::Error;
};

/// The device answered correctly but reported a failure (NAK, beam lost, over-range).
class DeviceError : public Error {
 public:
  using Error::Error;
};

/// Input from a user or a file is invalid (plan, CSV, command-line value).
/// The message names where (file, line, key) and why.
class InputError : public Error {
 public:
  using Error::Error;
};

/// The database could not be read or written (SQLite error, schema mismatch).
class StorageError : public Error {
 public:
  using Error::Error;
};

}  // namespace mtcal
