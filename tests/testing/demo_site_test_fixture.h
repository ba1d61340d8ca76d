#ifndef ROOMFIX_TESTS_TESTING_DEMO_SITE_TEST_FIXTURE_H_
#define ROOMFIX_TESTS_TESTING_DEMO_SITE_TEST_FIXTURE_H_

#include <gtest/gtest.h>

#include <string>

#include "core/world/site.h"
#include "tests/testing/demo_site.h"

namespace roomfix::testing {

// A test on the demo site (DemoSitePath()), loaded into site_, which has at
// least one camera.
class DemoSiteTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ASSERT_TRUE(LoadSite(DemoSitePath(), &site_, &error)) << error;
    ASSERT_FALSE(site_.cameras.empty());
  }
  Site site_;
};

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_DEMO_SITE_TEST_FIXTURE_H_
