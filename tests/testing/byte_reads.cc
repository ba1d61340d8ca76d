#include "tests/testing/byte_reads.h"

#include <poll.h>
#include <unistd.h>

#include <chrono>

namespace roomfix::testing {

std::vector<uint8_t> ReadFor(const std::function<int()>& fd,
                             const std::function<ssize_t(uint8_t*, size_t)>& read, size_t size,
                             int timeout_ms) {
  std::vector<uint8_t> out;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (out.size() < size && fd() >= 0 && std::chrono::steady_clock::now() < deadline) {
    pollfd p{fd(), POLLIN, 0};
    if (::poll(&p, 1, 10) <= 0) continue;
    uint8_t buffer[512];
    const ssize_t n = read(buffer, sizeof(buffer));
    if (n > 0) out.insert(out.end(), buffer, buffer + n);
  }
  return out;
}

std::vector<uint8_t> ReadFdFor(int fd, size_t size, int timeout_ms) {
  return ReadFor([fd] { return fd; },
                 [fd](uint8_t* buffer, size_t capacity) { return ::read(fd, buffer, capacity); },
                 size, timeout_ms);
}

std::vector<uint8_t> AllByteValues() {
  std::vector<uint8_t> bytes(256);
  for (int i = 0; i < 256; ++i) bytes[static_cast<size_t>(i)] = static_cast<uint8_t>(i);
  return bytes;
}

}  // namespace roomfix::testing
