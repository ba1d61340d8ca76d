#include "msgio/message_conversions.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "tests/testing/wire_test_messages.h"

namespace roomfix {
namespace {

template <typename Message>
std::vector<uint8_t> Encode(const Message& msg) {
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// Every field away from Pose2d's defaults and from every other field, so a
// field the conversion drops or swaps changes the encoded bytes.
pose2d_t DistinctPose() {
  pose2d_t p{};
  p.utime = 1700000000123456;
  p.source = pose2d_t::SOURCE_CAMERA;
  p.camera_id = 3;
  p.robot_id = 7;
  p.measurement_seq = 4242;
  p.x_m = 1.25;
  p.y_m = 2.5;
  p.z_m = 0.31;
  p.heading_rad = 0.75;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) p.covariance[r][c] = 1e-4 * (1 + 3 * r + c);
  }
  p.residual_m = 0.004;
  p.num_measurements = 2;
  p.status = pose2d_t::STATUS_DEGRADED;
  p.latency_us = 31000;
  return p;
}

TEST(MessageConversions, APoseSurvivesTheRoundTripByteForByte) {
  const pose2d_t msg = DistinctPose();
  EXPECT_EQ(Encode(ToMessage(FromMessage(msg))), Encode(msg));
}

TEST(MessageConversions, MarkerPixelsAndPreviewSurviveTheRoundTripByteForByte) {
  const marker_pixels_t pixels = testing::MakeTestMarkerPixels();
  EXPECT_EQ(Encode(ToMessage(FromMessage(pixels))), Encode(pixels));
  const image_t image = testing::MakeTestImage();
  EXPECT_EQ(Encode(ToMessage(FromMessage(image))), Encode(image));
}

TEST(MessageConversions, DetectorViewAndItsRequestSurviveTheRoundTripByteForByte) {
  const detector_view_t view = testing::MakeTestDetectorView();
  EXPECT_EQ(Encode(ToMessage(FromMessage(view))), Encode(view));
  const detector_view_request_t request = testing::MakeTestDetectorViewRequest();
  EXPECT_EQ(Encode(ToMessage(FromMessage(request))), Encode(request));
  DetectorViewImage counted;
  counted.data = {1, 2, 3};
  counted.robots.resize(2);
  const detector_view_t msg = ToMessage(counted);
  EXPECT_EQ(msg.num_bytes, 3);
  EXPECT_EQ(msg.num_robots, 2);
}

TEST(MessageConversions, APoseNobodyFilledInIsALostPoseWithNothingKnown) {
  const pose2d_t msg = ToMessage(Pose2d{});
  EXPECT_EQ(msg.status, pose2d_t::STATUS_LOST);
  EXPECT_EQ(msg.source, pose2d_t::SOURCE_UNKNOWN);
  EXPECT_EQ(msg.camera_id, kNoCameraId);
  EXPECT_EQ(msg.measurement_seq, -1);
  EXPECT_TRUE(std::isnan(msg.x_m) && std::isnan(msg.y_m) && std::isnan(msg.z_m));
  EXPECT_TRUE(std::isnan(msg.heading_rad));
  for (const auto& row : msg.covariance) {
    for (double v : row) EXPECT_TRUE(std::isnan(v));
  }
}

TEST(MessageConversions, CountsFollowTheVectors) {
  MarkerPixels pixels;
  pixels.markers.resize(3);
  pixels.markers[1].role = MarkerRole::kHeading;
  const marker_pixels_t msg = ToMessage(pixels);
  EXPECT_EQ(msg.num_markers, 3);
  EXPECT_EQ(msg.markers[1].role, marker_t::ROLE_HEADING);

  PreviewImage image;
  image.data = {1, 2, 3, 4, 5};
  EXPECT_EQ(ToMessage(image).num_bytes, 5);
}

TEST(MessageConversions, AnUnknownEnumValueIsKeptForTheReaderToRefuse) {
  pose2d_t msg = DistinctPose();
  msg.source = 42;
  msg.status = -3;
  const Pose2d pose = FromMessage(msg);
  EXPECT_STREQ(PoseSourceName(pose.source), "unknown");
  EXPECT_NE(pose.status, PoseStatus::kOk);
  EXPECT_NE(pose.status, PoseStatus::kDegraded);
  EXPECT_NE(pose.status, PoseStatus::kLost);
  EXPECT_EQ(ToMessage(pose).status, -3);
}

TEST(MessageConversions, PoseSourcesHaveTheNamesTheAnalysisGroupsBy) {
  EXPECT_STREQ(PoseSourceName(PoseSource::kCamera), "camera");
  EXPECT_STREQ(PoseSourceName(PoseSource::kUltrasound), "ultrasound");
  EXPECT_STREQ(PoseSourceName(PoseSource::kFused), "fused");
  EXPECT_STREQ(PoseSourceName(PoseSource::kGroundTruth), "ground_truth");
}

}  // namespace
}  // namespace roomfix
