// Counts heap allocations made by chosen threads, for the "the 1 kHz path never allocates" tests.
// Linking allocation_counter.cpp replaces every form of operator new and delete in the test
// binary (malloc and free underneath, so each pair still meets under sanitizers). A thread is
// counted while CountThisThread(true) is in force on it, or when it is the watched thread (a
// thread the test does not run itself, such as the UDP endpoint's I/O thread).
#pragma once

#include <thread>

namespace vsurg::test {

// False under ThreadSanitizer, whose runtime defines operator new itself (the tests skip there;
// the main and ASan builds run them).
bool CanCountAllocations();
void CountThisThread(bool on);
void WatchThread(std::thread::id id);  // std::thread::id(): none
void ResetAllocations();
long Allocations();

}  // namespace vsurg::test
