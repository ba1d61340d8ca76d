#include "zigbee_bridge/bridge_app.h"

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "tests/testing/check_context.h"

namespace roomfix {
namespace {

BridgeAppOptions ValidOptions() {
  BridgeAppOptions options;
  options.link.port = "/dev/ttyUSB0";
  return options;
}

TEST(BridgeAppOptionsTest, NeedsAPortAndAStandardBaudRate) {
  std::string error;
  EXPECT_TRUE(ValidOptions().IsValid(&error)) << error;
  EXPECT_FALSE(BridgeAppOptions().IsValid(&error));
  EXPECT_EQ(error, "serial port is empty");

  BridgeAppOptions options = ValidOptions();
  options.link.baud = 12345;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "baud 12345 is not a standard rate (1200 .. 921600)");
}

TEST(BridgeAppOptionsTest, RefusesANegativeDeadline) {
  BridgeAppOptions options = ValidOptions();
  options.node.assembler.deadline_s = -0.003;
  std::string error;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "deadline must be in (0, 10] s");
}

class RunBridgeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ctx_ = testing::DemoCheckContext("zigbee_bridge", &error);
    ASSERT_NE(ctx_, nullptr) << error;
  }
  std::unique_ptr<ProcessContext> ctx_;
};

TEST_F(RunBridgeTest, CheckPrintsThePortTheSiteAndTheDeadline) {
  BridgeAppOptions options = ValidOptions();
  options.node.api_mode = radio::ApiMode::kUnescaped;
  options.node.assembler.deadline_s = 0.0455;
  std::string error;
  ::testing::internal::CaptureStdout();
  EXPECT_EQ(RunBridge(ctx_.get(), options, &error), 0) << error;
  // The demo room: one coordinator hearing 4 receivers and 1 beacon.
  EXPECT_EQ(::testing::internal::GetCapturedStdout(),
            "zigbee_bridge: ok: /dev/ttyUSB0 at 115200 baud, API mode 1, 4 receivers, 1 beacons, "
            "deadline 45.5 ms, on memq://\n");
}

TEST_F(RunBridgeTest, RefusesARadioTheSiteDoesNotName) {
  BridgeAppOptions options = ValidOptions();
  options.radio_id = 7;
  std::string error;
  EXPECT_EQ(RunBridge(ctx_.get(), options, &error), 1);
  EXPECT_EQ(error, "--radio: the site names no radio 7 (it has no radios: section)");
}

}  // namespace
}  // namespace roomfix
