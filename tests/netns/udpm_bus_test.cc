// UdpmBus speaks LCM's multicast wire format itself: it must interoperate
// with liblcm both ways, for short and fragmented messages, and shrug off
// datagrams that are not LCM.
#include "msgio/udpm_bus.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>

#include "msgio/process.h"

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
  const auto big = Payload(70000, 1);  // Beyond one datagram: refused, counted.
  EXPECT_FALSE(ours->PublishRaw("FROM_US", big.data(), static_cast<int>(big.size())));
  EXPECT_EQ(ours->stats().publish_failures, 1);
  EXPECT_TRUE(HandleUntil(
      lcm.get(), [&] { return got.size() >= 20; }, 5.0));
  ASSERT_EQ(got.size(), 20u);
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
  EXPECT_EQ(ours->wire_stats().malformed, 4);
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
