#ifndef ROOMFIX_TESTS_TESTING_BYTE_READS_H_
#define ROOMFIX_TESTS_TESTING_BYTE_READS_H_

// Reading what a pseudo-terminal or serial link delivers, for tests: bytes
// trickle in over several reads, so a test waits for as many as it expects
// with a deadline instead of trusting one read.
#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace roomfix::testing {

// Polls fd() for input (10 ms at a time) and calls read(buffer, capacity)
// until `size` bytes came, fd() is negative (the device went away) or
// timeout_ms passed. May return more than `size` when a read delivers more.
std::vector<uint8_t> ReadFor(const std::function<int()>& fd,
                             const std::function<ssize_t(uint8_t*, size_t)>& read, size_t size,
                             int timeout_ms);

// ReadFor on a plain non-blocking file descriptor with ::read.
std::vector<uint8_t> ReadFdFor(int fd, size_t size, int timeout_ms);

// The bytes 0..255 in order: every value a binary link must pass unchanged.
std::vector<uint8_t> AllByteValues();

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_BYTE_READS_H_
