// UdpmBus speaks LCM's multicast wire format itself: it must interoperate
// with liblcm both ways, for short and fragmented messages, shrug off
// datagrams that are not LCM, keep hostile fragments within a fixed memory
// budget, and count every datagram it or the kernel dropped.
#include "msgio/udpm_bus.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "msgio/process.h"
#include "tests/testing/hostile_traffic.h"

namespace roomfix {
namespace {

std::vector<uint8_t> Payload(int size, int seed) {
  std::vector<uint8_t> b(static_cast<size_t>(size));
  for (int i = 0; i < size; ++i) b[static_cast<size_t>(i)] = static_cast<uint8_t>(seed + i * 7);
  return b;
}

TEST(UdpmBus, ReceivesShortAndFragmentedMessagesPublishedByLiblcm) {
  std::string error;
  auto ours = UdpmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(ours, nullptr) << error;
  auto lcm = LcmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(lcm, nullptr) << error;
  std::vector<std::pair<std::string, std::vector<uint8_t>>> got;
  ours->SubscribeRaw("DATA_.*", [&](const MessageInfo& info, const void* data, int size) {
    const auto* b = static_cast<const uint8_t*>(data);
    got.emplace_back(info.channel, std::vector<uint8_t>(b, b + size));
    EXPECT_GT(info.recv_utime, 1500000000000000);
  });
  // 200 kB is split by liblcm into four fragments. Each message is received
  // before the next is sent: four 64 kB datagrams already fill the kernel's
  // default receive buffer of a socket nobody is draining.
  const std::vector<int> sizes = {0, 1, 100, 1400, 65000, 200000};
  lcm->PublishRaw("OTHER", "x", 1);
  for (size_t k = 0; k < sizes.size(); ++k) {
    const auto p = Payload(sizes[k], static_cast<int>(k));
    ASSERT_TRUE(lcm->PublishRaw("DATA_" + std::to_string(k), p.data(), sizes[k]));
    EXPECT_TRUE(HandleUntil(
        ours.get(), [&] { return got.size() > k; }, 5.0));
  }
  ASSERT_EQ(got.size(), sizes.size());
  for (size_t k = 0; k < sizes.size(); ++k) {
    EXPECT_EQ(got[k].first, "DATA_" + std::to_string(k));
    EXPECT_EQ(got[k].second, Payload(sizes[k], static_cast<int>(k))) << "size " << sizes[k];
  }
  EXPECT_EQ(ours->wire_stats().malformed, 0);
}

TEST(UdpmBus, PublishesWhatLiblcmReceives) {
  std::string error;
  auto ours = UdpmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(ours, nullptr) << error;
  auto lcm = LcmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(lcm, nullptr) << error;
  std::vector<std::vector<uint8_t>> got;
  lcm->SubscribeRaw("FROM_US", [&](const MessageInfo&, const void* data, int size) {
    const auto* b = static_cast<const uint8_t*>(data);
    got.emplace_back(b, b + size);
  });
  for (int k = 0; k < 20; ++k) {
    const auto p = Payload(10 * k, k);
    ASSERT_TRUE(ours->PublishRaw("FROM_US", p.data(), static_cast<int>(p.size())));
  }
  EXPECT_TRUE(HandleUntil(
      lcm.get(), [&] { return got.size() >= 20; }, 5.0));
  // Beyond one datagram: sent in LC03 fragments as liblcm sends them (two and
  // four fragments), each received before the next is sent.
  for (int size : {70000, 200000}) {
    const auto big = Payload(size, 1);
    ASSERT_TRUE(ours->PublishRaw("FROM_US", big.data(), static_cast<int>(big.size())));
    const size_t before = got.size();
    EXPECT_TRUE(HandleUntil(
        lcm.get(), [&] { return got.size() > before; }, 5.0));
    ASSERT_EQ(got.size(), before + 1);
    EXPECT_EQ(got.back(), big);
  }
  EXPECT_EQ(ours->stats().publish_failures, 0);
  ASSERT_EQ(got.size(), 22u);
  for (int k = 0; k < 20; ++k) EXPECT_EQ(got[k], Payload(10 * k, k));
}

TEST(UdpmBus, CountsDatagramsThatAreNotLcmAndKeepsGoing) {
  std::string error;
  auto ours = UdpmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(ours, nullptr) << error;
  int delivered = 0;
  ours->SubscribeRaw(".*", [&](const MessageInfo&, const void*, int) { ++delivered; });
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(7667);
  inet_pton(AF_INET, "239.255.76.67", &to.sin_addr);
  const unsigned char ttl = 0;
  ::setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof(ttl));
  const std::vector<std::string> junk = {
      "abc",                                                    // too short
      std::string("LC02\0\0\0\1NOTERMINATOR", 20),              // channel without NUL
      std::string("XXXX\0\0\0\1CH\0data", 15),                  // unknown magic
      std::string("LC03\0\0\0\1\0\0\0\4\0\0\0\0\0\3\0\2", 20),  // fragment 3 of 2
  };
  for (const auto& j : junk) {
    ::sendto(fd, j.data(), j.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof(to));
  }
  ::close(fd);
  ours->PublishRaw("GOOD", "ok", 2);
  EXPECT_TRUE(HandleUntil(
      ours.get(), [&] { return delivered >= 1; }, 5.0));
  EXPECT_EQ(delivered, 1);
  EXPECT_EQ(ours->wire_stats().malformed, 3);
  EXPECT_EQ(ours->stats().datagrams_malformed, 3);
  EXPECT_EQ(ours->stats().fragments_malformed, 1);  // The LC03 one.
}

// ---------------------------------------------------------------------------
// Hostile fragments (issue #15): whatever LC03 datagrams arrive, memory stays
// within FragmentLimits, good messages still arrive, and every refusal is
// counted by cause.

// Sends raw datagrams to the default group from one socket (one source
// address and port, as one sender).
class RawSender {
 public:
  RawSender() : fd_(::socket(AF_INET, SOCK_DGRAM, 0)) {
    to_.sin_family = AF_INET;
    to_.sin_port = htons(7667);
    inet_pton(AF_INET, "239.255.76.67", &to_.sin_addr);
    const unsigned char ttl = 0;
    ::setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof(ttl));
  }
  ~RawSender() { ::close(fd_); }
  void Send(const std::vector<uint8_t>& d) {
    ASSERT_EQ(::sendto(fd_, d.data(), d.size(), 0, reinterpret_cast<sockaddr*>(&to_), sizeof(to_)),
              static_cast<ssize_t>(d.size()));
  }
  // An LC03 fragment; fragment 0 gets the channel before its data.
  void Fragment(uint32_t seqno, uint32_t total, uint32_t offset, uint16_t number, uint16_t count,
                const std::string& channel, size_t data_bytes) {
    const std::vector<uint8_t> d = hostile::FragmentDatagram(
        seqno, total, offset, number, count, channel, hostile::Bytes(data_bytes, 0x5A));
    Send(d);
  }

 private:
  int fd_;
  sockaddr_in to_{};
};

int64_t ResidentKb() {
  FILE* f = std::fopen("/proc/self/status", "r");
  char line[256];
  int64_t kb = -1;
  while (f != nullptr && std::fgets(line, sizeof(line), f) != nullptr) {
    if (std::strncmp(line, "VmRSS:", 6) == 0) kb = std::atoll(line + 6);
  }
  if (f != nullptr) std::fclose(f);
  return kb;
}

struct Received {
  std::vector<std::string> channels;
  std::vector<int> sizes;
};

std::unique_ptr<UdpmBus> Listen(Received* got, const FragmentLimits& limits = FragmentLimits()) {
  std::string error;
  auto bus = UdpmBus::Create(kDefaultLcmUrl, &error, limits);
  EXPECT_NE(bus, nullptr) << error;
  if (bus == nullptr) return nullptr;
  bus->SubscribeRaw(".*", [got](const MessageInfo& info, const void*, int size) {
    got->channels.push_back(info.channel);
    got->sizes.push_back(size);
  });
  return bus;
}

// Waits until n more messages arrived, and a little after for stragglers.
void Drain(UdpmBus* bus, const Received& got, size_t n) {
  EXPECT_TRUE(HandleUntil(
      bus, [&] { return got.channels.size() >= n; }, 5.0));
  HandleUntil(
      bus, [] { return false; }, 0.1);
}

TEST(UdpmBusFragments, TotalsThatDisagreeAreRefusedNeverCopied) {
  Received got;
  auto bus = Listen(&got);
  ASSERT_NE(bus, nullptr);
  RawSender raw;
  // The input that overflowed the heap: fragment 0 declares 100 bytes,
  // fragment 1 of the same message 70 000 and carries 60 000 at offset 50.
  raw.Fragment(1, 100, 0, 0, 2, "MM", 50);
  raw.Fragment(1, 70000, 50, 1, 2, "", 60000);
  // liblcm 1.3.1's crasher: offset + size wraps in 32 bits.
  raw.Fragment(2, 1000, 0xFFFFFF00u, 0, 2, "MM", 0x200);
  bus->PublishRaw("GOOD", "ok", 2);
  Drain(bus.get(), got, 1);
  EXPECT_EQ(got.channels, std::vector<std::string>{"GOOD"});
  EXPECT_EQ(bus->stats().fragments_malformed, 2);
  // The message of fragment 0 is still waiting for its real fragment 1.
  EXPECT_EQ(bus->partial_bytes(), 100);
}

TEST(UdpmBusFragments, SixtyFourMebibyteFirstFragmentsNeitherBloatNorCrowdOutGoodMessages) {
  constexpr int kHostile = 200;
  constexpr int kGood = 800;
  // Heap the test itself and the kernel's bookkeeping may add; far below one
  // 64 MiB message.
  constexpr int64_t kSlackKb = 16 << 10;
  const FragmentLimits limits;
  Received got;
  auto bus = Listen(&got, limits);
  ASSERT_NE(bus, nullptr);
  const int64_t rss_before_kb = ResidentKb();
  RawSender raw;
  int good_sent = 0;
  for (int k = 0; k < kHostile; ++k) {
    raw.Fragment(uint32_t(100 + k), 64u << 20, 0, 0, 1100, "BIG", 1000);
    for (int g = 0; g < kGood / kHostile; ++g) {
      bus->PublishRaw("GOOD", "ok", 2);
      ++good_sent;
    }
    // Drained every few datagrams, as a process keeps up with traffic;
    // the kernel buffer is not what this test is about.
    if (k % 10 == 9) bus->Handle(0);
  }
  Drain(bus.get(), got, kGood);
  EXPECT_EQ(good_sent, kGood);
  EXPECT_EQ(std::count(got.channels.begin(), got.channels.end(), "GOOD"), kGood);
  EXPECT_EQ(bus->stats().fragments_over_budget, kHostile);  // Each over the per-message cap.
  EXPECT_EQ(bus->stats().dropped_kernel_overflow, 0);
  EXPECT_EQ(bus->partial_bytes(), 0);
  EXPECT_LT(ResidentKb() - rss_before_kb, kSlackKb);
}

TEST(UdpmBusFragments, PartialMessagesTogetherStayWithinTheBudget) {
  // 4 MiB is under the per-message cap, so each would be held: the budget
  // admits limits.budget_bytes / 4 MiB of them and refuses the rest.
  constexpr int kMessages = 40;
  constexpr uint32_t kTotal = 4u << 20;
  constexpr int64_t kSlackKb = 16 << 10;
  const FragmentLimits limits;
  Received got;
  auto bus = Listen(&got, limits);
  ASSERT_NE(bus, nullptr);
  const int64_t rss_before_kb = ResidentKb();
  RawSender raw;
  for (int k = 0; k < kMessages; ++k) {
    raw.Fragment(uint32_t(500 + k), kTotal, 0, 0, 70, "BIG", 1000);
    if (k % 10 == 9) bus->Handle(0);
  }
  bus->PublishRaw("GOOD", "ok", 2);
  Drain(bus.get(), got, 1);
  const int admitted = static_cast<int>(limits.budget_bytes / kTotal);
  EXPECT_EQ(bus->partial_bytes(), int64_t{admitted} * kTotal);
  EXPECT_EQ(bus->stats().fragments_over_budget, kMessages - admitted);
  EXPECT_LT(ResidentKb() - rss_before_kb, limits.budget_bytes / 1024 + kSlackKb);
  EXPECT_EQ(got.channels, std::vector<std::string>{"GOOD"});
}

TEST(UdpmBusFragments, DuplicateFragmentsAreDroppedAndTheMessageArrivesOnce) {
  Received got;
  auto bus = Listen(&got);
  ASSERT_NE(bus, nullptr);
  RawSender raw;
  raw.Fragment(7, 3000, 0, 0, 2, "DUP", 1000);
  raw.Fragment(7, 3000, 0, 0, 2, "DUP", 1000);
  raw.Fragment(7, 3000, 1000, 1, 2, "", 2000);
  raw.Fragment(7, 3000, 1000, 1, 2, "", 2000);  // After completion: a new partial.
  Drain(bus.get(), got, 1);
  EXPECT_EQ(got.channels, std::vector<std::string>{"DUP"});
  EXPECT_EQ(got.sizes, std::vector<int>{3000});
  EXPECT_EQ(bus->stats().fragments_duplicate, 1);
}

TEST(UdpmBusFragments, AnIncompleteMessageExpiresAndIsCounted) {
  FragmentLimits limits;
  limits.expiry_us = 100000;
  Received got;
  auto bus = Listen(&got, limits);
  ASSERT_NE(bus, nullptr);
  RawSender raw;
  raw.Fragment(9, 3000, 0, 0, 3, "LATE", 1000);
  raw.Fragment(9, 3000, 1000, 1, 3, "", 1000);
  HandleUntil(
      bus.get(), [] { return false; }, 0.05);
  EXPECT_EQ(bus->partial_bytes(), 3000);
  // Three expiry periods with no traffic: Handle's time-outs expire it.
  HandleUntil(
      bus.get(), [] { return false; }, 0.3);
  EXPECT_EQ(bus->partial_bytes(), 0);
  EXPECT_EQ(bus->stats().fragments_expired, 2);  // The two fragments it held.
  EXPECT_TRUE(got.channels.empty());
}

TEST(UdpmBus, CountsWhatTheKernelDroppedWhileNobodyRead) {
  // A small buffer (the kernel's minimum is a few KiB) and a burst with
  // nobody reading: most datagrams are dropped by the kernel, and every one
  // is either delivered or counted, exactly (nothing else is on this
  // namespace's bus during the test).
  constexpr int kSent = 2000;
  std::string error;
  auto bus = UdpmBus::Create(std::string(kDefaultLcmUrl) + "&recv_buf_size=16384", &error);
  ASSERT_NE(bus, nullptr) << error;
  int delivered = 0;
  bus->SubscribeRaw("BURST", [&](const MessageInfo&, const void*, int) { ++delivered; });
  RawSender raw;
  const std::vector<uint8_t> burst = {'L', 'C', '0', '2', 0, 0, 0, 1, 'B',
                                      'U', 'R', 'S', 'T', 0, 1, 2, 3, 4};
  for (int k = 0; k < kSent; ++k) raw.Send(burst);
  bus->RefreshStats();
  const int64_t dropped_before_reading = bus->stats().dropped_kernel_overflow;
  HandleUntil(
      bus.get(), [] { return false; }, 0.3);
  bus->RefreshStats();
  EXPECT_GT(dropped_before_reading, kSent / 2);
  EXPECT_EQ(bus->stats().dropped_kernel_overflow, dropped_before_reading);
  EXPECT_EQ(delivered + bus->stats().dropped_kernel_overflow, kSent);
}

TEST(ParseUdpmUrl, ReadsGroupPortAndOptions) {
  UdpmAddress a;
  std::string error;
  ASSERT_TRUE(ParseUdpmUrl("udpm://239.255.76.68:7668?ttl=1&recv_buf_size=4096", &a, &error));
  EXPECT_EQ(a.group, "239.255.76.68");
  EXPECT_EQ(a.port, 7668);
  EXPECT_EQ(a.ttl, 1);
  EXPECT_EQ(a.recv_buf_size, 4096);
  EXPECT_FALSE(ParseUdpmUrl("udpm://not.an.address:1", &a, &error));
  EXPECT_FALSE(ParseUdpmUrl("memq://", &a, &error));
}

}  // namespace
}  // namespace roomfix
