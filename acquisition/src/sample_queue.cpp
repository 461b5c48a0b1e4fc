#include "mtcal/acquisition/sample_queue.h"

namespace mtcal::acquisition {

void SampleQueue::push(std::span<const drivers::Sample> samples) {
  std::unique_lock lock(mutex_);
  std::size_t i = 0;
  while (i < samples.size()) {
    if (samples_.size() >= capacity_) {
      if (policy_ == OverflowPolicy::kDropNewest || closed_) {
        dropped_ += samples.size() - i;
        break;
      }
      not_full_.wait(lock, [&] { return samples_.size() < capacity_ || closed_; });
      continue;
    }
    const std::size_t n = std::min(samples.size() - i, capacity_ - samples_.size());
    samples_.insert(samples_.end(), samples.begin() + static_cast<std::ptrdiff_t>(i),
                    samples.begin() + static_cast<std::ptrdiff_t>(i + n));
    i += n;
    not_empty_.notify_one();
  }
}

std::size_t SampleQueue::popBatch(std::vector<drivers::Sample>& out, std::size_t max,
                                  std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  if (!not_empty_.wait_for(lock, timeout, [&] { return !samples_.empty() || closed_; })) return 0;
  const std::size_t n = std::min(max, samples_.size());
  out.insert(out.end(), samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(n));
  samples_.erase(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(n));
  lock.unlock();
  not_full_.notify_one();
  return n;
}

std::size_t SampleQueue::clear() {
  std::lock_guard lock(mutex_);
  const std::size_t n = samples_.size();
  samples_.clear();
  not_full_.notify_all();
  return n;
}

void SampleQueue::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  not_full_.notify_all();
  not_empty_.notify_all();
}

std::uint64_t SampleQueue::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

std::size_t SampleQueue::size() const {
  std::lock_guard lock(mutex_);
  return samples_.size();
}

}  // namespace mtcal::acquisition
