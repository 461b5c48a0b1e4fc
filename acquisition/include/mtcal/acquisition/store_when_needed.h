#pragma once
// The store an import writes to, asked for only once the file has been read whole and found
// sound: a command whose import fails creates no store (a store opened on demand is created
// where it is missing).

#include <functional>
#include <utility>

#include "mtcal/storage/store.h"

namespace mtcal::acquisition {

class StoreWhenNeeded {
 public:
  /// A store open already.
  StoreWhenNeeded(storage::Store& store)  // NOLINT(google-explicit-constructor): a store is one
      : open_([&store]() -> storage::Store& { return store; }) {}
  /// A store opened (or created) by `open` when the import has something to store.
  explicit StoreWhenNeeded(std::function<storage::Store&()> open) : open_(std::move(open)) {}
  storage::Store& operator()() const { return open_(); }

 private:
  std::function<storage::Store&()> open_;
};

}  // namespace mtcal::acquisition
