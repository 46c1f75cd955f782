#include "tests/support/allocation_counter.h"

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
thread_local bool g_counting = false;
std::atomic<long> g_allocations{0};
std::atomic<std::thread::id> g_watched{};
}  // namespace

// ThreadSanitizer's runtime (clang) defines operator new and delete itself: no replacement there,
// and the allocation test is skipped in that build (the main and ASan builds run it).
#if defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define VSURG_NO_NEW_REPLACEMENT 1
#endif
#endif
#if defined(__SANITIZE_THREAD__)
#define VSURG_NO_NEW_REPLACEMENT 1
#endif

#ifndef VSURG_NO_NEW_REPLACEMENT
namespace {
bool Counted() {
  return g_counting || std::this_thread::get_id() == g_watched.load(std::memory_order_relaxed);
}
}  // namespace

// The replacements pair malloc with free themselves; GCC cannot see that through inlining.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t n) {
  if (Counted()) g_allocations.fetch_add(1);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  if (Counted()) g_allocations.fetch_add(1);
  return std::malloc(n ? n : 1);
}
void* operator new[](std::size_t n) {
  return operator new(n);
}
void* operator new[](std::size_t n, const std::nothrow_t& t) noexcept {
  return operator new(n, t);
}
void operator delete(void* p) noexcept {
  std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete(void* p, const std::nothrow_t&) noexcept {
  std::free(p);
}
void operator delete[](void* p) noexcept {
  std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
  std::free(p);
}
void operator delete[](void* p, const std::nothrow_t&) noexcept {
  std::free(p);
}
#endif  // VSURG_NO_NEW_REPLACEMENT

namespace vsurg::test {

bool CanCountAllocations() {
#ifdef VSURG_NO_NEW_REPLACEMENT
  return false;
#else
  return true;
#endif
}
void CountThisThread(bool on) {
  g_counting = on;
}
void WatchThread(std::thread::id id) {
  g_watched.store(id);
}
void ResetAllocations() {
  g_allocations.store(0);
}
long Allocations() {
  return g_allocations.load();
}

}  // namespace vsurg::test
