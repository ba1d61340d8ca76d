#include "tests/testing/hostile_classes.h"

#include <gtest/gtest.h>

#include <string>

namespace roomfix::hostile {
namespace {

TEST(PublisherOptionsTest, TakesEveryClassByNameAndRefusesAnUnknownOne) {
  PublisherOptions options;
  std::string error;
  // issue #15's table, one class a row.
  EXPECT_EQ(TrafficClasses().size(), 9u);
  for (const auto& [name, traffic] : TrafficClasses()) {
    options.class_name = name;
    EXPECT_TRUE(options.IsValid(&error)) << name << ": " << error;
    EXPECT_FALSE(traffic.description.empty()) << name;
  }
  options.class_name = "nosuchclass";
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "unknown class 'nosuchclass'");
}

TEST(SendTrafficTest, RefusesAUrlItCannotSendRawDatagramsTo) {
  // The sender writes LCM datagrams itself; memq:// has no socket to write.
  PublisherOptions options;
  options.lcm_url = "memq://";
  options.class_name = "empty-channel";
  std::string error;
  EXPECT_EQ(SendTraffic(options, &error), 1);
  EXPECT_EQ(error, "memq://: not a udpm:// URL");
}

}  // namespace
}  // namespace roomfix::hostile
