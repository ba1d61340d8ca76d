#ifndef ROOMFIX_TESTS_TESTING_FORGED_SITE_H_
#define ROOMFIX_TESTS_TESTING_FORGED_SITE_H_

// Forged SITE messages of issue #28: valid on every check a receiver makes
// (their content hash matches their texts, the site text is the demo's), but
// carrying texts built to make comparing them with --config expensive. For
// msgio/site_message_test.cc, tests/tools/site_from_log_test.cc and
// tests/netns/hostile_traffic_test.cc.

#include <cstddef>
#include <string>
#include <vector>

#include "roomfix/site_t.hpp"

namespace roomfix::testing {

// The demo site's own text and, under the name of its camera's calibration
// file, a flat mapping of `keys` numbers ("k0: 0.5", "k1: 1.5", ...; the
// issue's 259 KB text has about 13 600 of them), with `variant` in its first
// value so that each variant is a distinct site with its own valid hash.
site_t ForgedSiteWithFlatCalibration(size_t keys, int variant, const std::string& process);
// The calibration text of that site.
std::string FlatCalibrationText(size_t keys, int variant);
// The number of keys whose text is about `bytes` long.
size_t FlatKeysForBytes(size_t bytes);

// The same with a calibration text of `levels` anchors, each a list of
// `fan_out` aliases of the one before, the first an anchor of `leaf`: a few
// hundred bytes that expand into fan_out^levels nodes when walked as a tree.
site_t ForgedSiteWithAliasBomb(int levels, int fan_out, const std::string& leaf,
                               const std::string& process);
std::string AliasBombText(int levels, int fan_out, const std::string& leaf);

// The demo site's calibration with `site_text` as the site, with its hash.
site_t ForgedSiteWithText(const std::string& site_text, const std::string& process);

// Copies the log `from` to `to` without its SITE events and with `sites`
// (in order, at the first event's time) before its first event. False with
// *error when a log cannot be read or written.
bool CopyLogWithSites(const std::string& from, const std::string& to,
                      const std::vector<site_t>& sites, std::string* error);
bool CopyLogWithSite(const std::string& from, const std::string& to, const site_t& site,
                     std::string* error);

// The demo site carrying, beside its calibration, 15 more files of 255 KiB
// (names the site does not use; `variant` in each): about 4 MB, near the
// 5 MiB a site_t may carry, each variant a distinct site.
site_t ForgedSiteWithLargeFiles(int variant, const std::string& process);

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_FORGED_SITE_H_
