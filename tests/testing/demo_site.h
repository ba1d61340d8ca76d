#ifndef ROOMFIX_TESTS_TESTING_DEMO_SITE_H_
#define ROOMFIX_TESTS_TESTING_DEMO_SITE_H_

// The demo site (config/sites/demo_room.yaml) and variants of it, for tests
// that run processes or tools on a site a little different from the demo's.
#include <string>

#include "tests/testing/test_paths.h"

namespace roomfix::testing {

// config/sites/demo_room.yaml in the source tree.
std::string DemoSitePath();

// A copy of the demo site with the text `from` replaced by `to`, written as
// DIR/sites/NAME.yaml beside a copy of config/calibration/demo_room_camera.yaml
// in DIR/calibration (the site names its calibration by a relative path, so
// the copy loads as the original does). Returns the new site's path, or ""
// with *error set when `from` is not in the site or a file cannot be written.
std::string WriteDemoSiteVariant(const TempDir& dir, const std::string& name,
                                 const std::string& from, const std::string& to,
                                 std::string* error);

// The demo site's text with `extra` receivers after its four (ids 1001 up,
// addresses of their own, spread over the room at the corners' height):
// never heard by the demo's beacon, valid otherwise. Issue #28's survey of a
// log whose site named 1 000 receivers ran 76 s.
std::string DemoSiteTextWithReceivers(size_t extra);

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_DEMO_SITE_H_
