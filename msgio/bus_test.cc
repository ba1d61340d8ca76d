#include "msgio/bus.h"

#include <gtest/gtest.h>

#include <climits>
#include <map>
#include <stdexcept>
#include <vector>

#include "roomfix/process_status_t.hpp"
#include "tests/testing/test_messages.h"
#include "tests/testing/wire_test_messages.h"

namespace roomfix {
namespace {

using testing::MakeTestPose;

std::unique_ptr<LcmBus> MemqBus() {
  std::string error;
  auto bus = LcmBus::Create("memq://", &error);
  EXPECT_NE(bus, nullptr) << error;
  return bus;
}

TEST(LcmBus, DeliversATypedMessageOverMemq) {
  auto bus = MemqBus();
  std::vector<pose2d_t> got;
  std::vector<std::string> channels;
  bus->Subscribe<pose2d_t>("POSE_.*", [&](const pose2d_t& p, const MessageInfo& info) {
    got.push_back(p);
    channels.push_back(info.channel);
  });
  ASSERT_TRUE(bus->Publish("POSE_ULTRASOUND", MakeTestPose(1000, 7, 1.5, 2.25)));
  ASSERT_TRUE(bus->Publish("OTHER", MakeTestPose(2000, 8, 0, 0)));
  while (bus->Handle(0) > 0) {
  }
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(channels[0], "POSE_ULTRASOUND");
  EXPECT_EQ(got[0].robot_id, 7);
  EXPECT_EQ(got[0].x_m, 1.5);
  EXPECT_EQ(got[0].y_m, 2.25);
  EXPECT_TRUE(std::isnan(got[0].heading_rad));
  EXPECT_EQ(bus->stats().published, 2);
}

TEST(LcmBus, CountsAMessageOfTheWrongTypeInsteadOfDeliveringIt) {
  auto bus = MemqBus();
  int delivered = 0;
  bus->Subscribe<pose2d_t>("POSE", [&](const pose2d_t&, const MessageInfo&) { ++delivered; });
  process_status_t status{};
  status.utime = 1;
  ASSERT_TRUE(bus->Publish("POSE", status));
  const uint8_t garbage[5] = {1, 2, 3, 4, 5};
  ASSERT_TRUE(bus->PublishRaw("POSE", garbage, sizeof(garbage)));
  while (bus->Handle(0) > 0) {
  }
  EXPECT_EQ(delivered, 0);
  EXPECT_EQ(bus->stats().decode_failures, 2);
  EXPECT_EQ(bus->stats().refused,
            (std::map<std::string, int64_t>{{"POSE.truncated", 1}, {"POSE.wrong_type", 1}}));
  EXPECT_EQ(bus->stats().last_error,
            "message on POSE refused (truncated): pose2d_t: 5 bytes, fewer than the 8-byte "
            "fingerprint");
}

TEST(LcmBus, CountsATruncatedMessage) {
  auto bus = MemqBus();
  int delivered = 0;
  bus->Subscribe<pose2d_t>("POSE", [&](const pose2d_t&, const MessageInfo&) { ++delivered; });
  const pose2d_t pose = MakeTestPose(1, 1, 1, 1);
  std::vector<uint8_t> bytes(pose.getEncodedSize());
  pose.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  bus->PublishRaw("POSE", bytes.data(), static_cast<int>(bytes.size()) - 3);
  while (bus->Handle(0) > 0) {
  }
  EXPECT_EQ(delivered, 0);
  EXPECT_EQ(bus->stats().decode_failures, 1);
  EXPECT_EQ(bus->stats().refused, (std::map<std::string, int64_t>{{"POSE.truncated", 1}}));
}

// A status outside pose2d_t's constants would cast to a PoseStatus no switch
// names and read as "not lost": refused before the handler, by channel.
TEST(LcmBus, RefusesAnEnumOutsideItsConstantsAndCountsItByChannel) {
  auto bus = MemqBus();
  std::vector<pose2d_t> got;
  bus->Subscribe<pose2d_t>("POSE_CAMERA",
                           [&](const pose2d_t& p, const MessageInfo&) { got.push_back(p); });
  pose2d_t bad_status = MakeTestPose(1000, 1, 1.5, 2.25);
  bad_status.status = 7;
  pose2d_t bad_source = MakeTestPose(2000, 1, 1.5, 2.25);
  bad_source.source = -1;
  ASSERT_TRUE(bus->Publish("POSE_CAMERA", bad_status));
  ASSERT_TRUE(bus->Publish("POSE_CAMERA", bad_source));
  ASSERT_TRUE(bus->Publish("POSE_CAMERA", MakeTestPose(3000, 1, 1.5, 2.25)));
  while (bus->Handle(0) > 0) {
  }
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].utime, 3000);
  EXPECT_EQ(bus->stats().decode_failures, 2);
  EXPECT_EQ(bus->stats().refused,
            (std::map<std::string, int64_t>{{"POSE_CAMERA.enum_out_of_range", 2}}));
  EXPECT_EQ(bus->stats().last_error,
            "message on POSE_CAMERA refused (enum_out_of_range): pose2d_t.source -1 outside 0..4 "
            "at byte 16 of 158");
}

// The audit's crash of every STATUS listener: a string length of INT32_MIN.
TEST(LoopbackBus, RefusesAHostileLengthBeforeTheHandlerAndCountsItByChannel) {
  LoopbackBus bus;
  int delivered = 0;
  bus.Subscribe<process_status_t>(
      "STATUS", [&](const process_status_t&, const MessageInfo&) { ++delivered; });
  std::vector<uint8_t> bytes = testing::Encode(testing::MakeTestStatus());
  bus.Inject("STATUS", bytes.data(), static_cast<int>(bytes.size()), 1);
  testing::PutInt32(&bytes, testing::kStatusProcessLengthOffset, INT32_MIN);
  bus.Inject("STATUS", bytes.data(), static_cast<int>(bytes.size()), 2);
  EXPECT_EQ(delivered, 1);
  EXPECT_EQ(bus.stats().refused, (std::map<std::string, int64_t>{{"STATUS.negative_length", 1}}));
}

// Channel names are the sender's choice: the map of refusals stays bounded
// however many it invents.
TEST(LoopbackBus, FoldsRefusalsBeyondTheChannelLimitIntoOther) {
  LoopbackBus bus;
  bus.Subscribe<pose2d_t>(".*", [](const pose2d_t&, const MessageInfo&) {});
  const uint8_t garbage[3] = {1, 2, 3};
  constexpr int kInvented = 1000;
  for (int i = 0; i < kInvented; ++i) {
    bus.Inject("X" + std::to_string(i), garbage, sizeof(garbage), i);
  }
  bus.Inject("X0", garbage, sizeof(garbage), kInvented);  // a named one stays named
  const BusStats stats = bus.stats();
  EXPECT_EQ(stats.decode_failures, kInvented + 1);
  EXPECT_EQ(stats.refused.size(), static_cast<size_t>(kMaxRefusedChannels) + 1);
  EXPECT_EQ(stats.refused.at("X0.truncated"), 2);
  EXPECT_EQ(stats.refused.at("<other>.truncated"), kInvented - kMaxRefusedChannels);
  EXPECT_EQ(stats.refused.count("X64.truncated"), 0u);
}

TEST(LcmBus, AThrowingHandlerIsCountedAndDoesNotUnwindIntoLcm) {
  auto bus = MemqBus();
  int after = 0;
  bus->Subscribe<pose2d_t>(
      "POSE", [](const pose2d_t&, const MessageInfo&) { throw std::runtime_error("boom"); });
  bus->Subscribe<pose2d_t>("POSE", [&](const pose2d_t&, const MessageInfo&) { ++after; });
  bus->Publish("POSE", MakeTestPose(1, 1, 1, 1));
  while (bus->Handle(0) > 0) {
  }
  EXPECT_EQ(bus->stats().handler_exceptions, 1);
  EXPECT_EQ(after, 1);
  EXPECT_EQ(bus->stats().last_error, "handler for POSE threw: boom");
}

TEST(LcmBus, StopsDeliveringAfterUnsubscribe) {
  auto bus = MemqBus();
  int delivered = 0;
  const SubscriptionId id =
      bus->Subscribe<pose2d_t>("POSE", [&](const pose2d_t&, const MessageInfo&) { ++delivered; });
  bus->Publish("POSE", MakeTestPose(1, 1, 1, 1));
  while (bus->Handle(0) > 0) {
  }
  bus->Unsubscribe(id);
  bus->Publish("POSE", MakeTestPose(2, 1, 1, 1));
  while (bus->Handle(0) > 0) {
  }
  EXPECT_EQ(delivered, 1);
}

TEST(LcmBus, RefusesAnUnknownUrlWithOneLine) {
  std::string error;
  EXPECT_EQ(LcmBus::Create("carrier-pigeon://", &error), nullptr);
  EXPECT_NE(error.find("cannot start LCM on 'carrier-pigeon://'"), std::string::npos) << error;
}

TEST(ChannelPattern, MatchesTheWholeNameLikeLcm) {
  EXPECT_TRUE(ChannelMatches("POSE", "POSE"));
  EXPECT_FALSE(ChannelMatches("POSE", "POSE_CAMERA"));
  EXPECT_TRUE(ChannelMatches("POSE_.*", "POSE_CAMERA"));
  EXPECT_TRUE(ChannelMatches("POSE_CAMERA|RANGES", "RANGES"));
  EXPECT_FALSE(ChannelMatches("POSE_CAMERA|RANGES", "XRANGES"));
  EXPECT_FALSE(ChannelMatches("(", "("));  // An invalid expression matches nothing.
}

TEST(LoopbackBus, DeliversSynchronouslyWithTheGivenReceiveTime) {
  LoopbackBus bus;
  std::vector<int64_t> times;
  bus.Subscribe<pose2d_t>(
      ".*", [&](const pose2d_t&, const MessageInfo& info) { times.push_back(info.recv_utime); });
  const pose2d_t pose = MakeTestPose(5, 1, 1, 1);
  std::vector<uint8_t> bytes(pose.getEncodedSize());
  pose.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  bus.Inject("A", bytes.data(), static_cast<int>(bytes.size()), 123);
  EXPECT_EQ(bus.now_utime(), 123);
  // A node publishing from a handler is stamped with the bus clock.
  bus.Publish("B", pose);
  EXPECT_EQ(times, (std::vector<int64_t>{123, 123}));
}

TEST(LoopbackBus, AHandlerMayPublishAndUnsubscribeWhileBeingCalled) {
  LoopbackBus bus;
  int outputs = 0;
  SubscriptionId self = 0;
  self = bus.Subscribe<pose2d_t>("IN", [&](const pose2d_t& p, const MessageInfo&) {
    bus.Publish("OUT", p);
    bus.Unsubscribe(self);
  });
  bus.Subscribe<pose2d_t>("OUT", [&](const pose2d_t&, const MessageInfo&) { ++outputs; });
  bus.Publish("IN", MakeTestPose(1, 1, 1, 1));
  bus.Publish("IN", MakeTestPose(2, 1, 1, 1));
  EXPECT_EQ(outputs, 1);
}

}  // namespace
}  // namespace roomfix
