// Lock-free single-producer single-consumer ring buffer of fixed capacity (a power of two): the
// interrupt handlers produce events, the main loop consumes them. No heap; the indices are
// free-running 32-bit counters (their difference is the fill level, correct across wrap-around),
// and acquire/release ordering publishes a slot before the index that exposes it. Hand-written
// because the core may use no library beyond the freestanding C++ headers.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>

namespace hc::fw {

template <typename T, std::size_t N>
class SpscRing {
  static_assert(N >= 2 && (N & (N - 1)) == 0, "capacity must be a power of two");
  static_assert(N <= (std::size_t{1} << 31), "capacity must fit the 32-bit index arithmetic");

 public:
  static constexpr std::size_t kCapacity = N;

  SpscRing() = default;
  // Starts both indices at `start_index` (tests use it to exercise the 32-bit wrap-around).
  explicit SpscRing(std::uint32_t start_index) : head_(start_index), tail_(start_index) {}

  // Producer side. Returns false (and stores nothing) when the ring is full.
  bool push(const T& value) {
    const std::uint32_t head = head_.load(std::memory_order_relaxed);
    const std::uint32_t tail = tail_.load(std::memory_order_acquire);
    if (head - tail == N) return false;
    slots_[head & (N - 1)] = value;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  // Consumer side. Returns false when the ring is empty.
  bool pop(T* out) {
    const std::uint32_t tail = tail_.load(std::memory_order_relaxed);
    const std::uint32_t head = head_.load(std::memory_order_acquire);
    if (head == tail) return false;
    *out = slots_[tail & (N - 1)];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  // Either side; a snapshot.
  std::size_t size() const {
    return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire);
  }
  bool empty() const { return size() == 0; }

 private:
  T slots_[N] = {};
  std::atomic<std::uint32_t> head_{0};  // written by the producer only
  std::atomic<std::uint32_t> tail_{0};  // written by the consumer only
};

}  // namespace hc::fw
