#include "tests/testing/forged_site.h"

#include <stdexcept>
#include <vector>

#include "msgio/log.h"
#include "msgio/site_message.h"
#include "tests/testing/demo_site.h"

namespace roomfix::testing {
namespace {

// The demo site with its text or its one calibration file's text replaced
// (when not empty): the hash is computed over the new texts, as a forger
// with sha256sum would.
site_t DemoSiteWith(const std::string& site_text, const std::string& calibration,
                    const std::string& process) {
  LoadedSite loaded;
  std::string error;
  if (!LoadSiteWithTexts(DemoSitePath(), &loaded, &error) || loaded.texts.files.size() != 1) {
    throw std::runtime_error("demo site: " + error);
  }
  if (!site_text.empty()) loaded.texts.site_text = site_text;
  if (!calibration.empty()) loaded.texts.files.begin()->second = calibration;
  loaded.content_hash = SiteContentHash(loaded.texts);
  site_t msg;
  if (!MakeSiteMessage(loaded, process, 1700000000000000, &msg, &error)) {
    throw std::runtime_error("forged site: " + error);
  }
  return msg;
}

std::string FlatLine(size_t i, int variant) {
  return "k" + std::to_string(i) + ": " + std::to_string(i) + "." +
         std::to_string(i == 0 ? variant : 5) + "\n";
}

}  // namespace

std::string FlatCalibrationText(size_t keys, int variant) {
  std::string text;
  for (size_t i = 0; i < keys; ++i) text += FlatLine(i, variant);
  return text;
}

size_t FlatKeysForBytes(size_t bytes) {
  size_t keys = 0;
  for (size_t total = 0; total < bytes; ++keys) total += FlatLine(keys, 0).size();
  return keys;
}

site_t ForgedSiteWithFlatCalibration(size_t keys, int variant, const std::string& process) {
  return DemoSiteWith("", FlatCalibrationText(keys, variant), process);
}

std::string AliasBombText(int levels, int fan_out, const std::string& leaf) {
  std::string text = "l0: &l0 " + leaf + "\n";
  for (int level = 1; level <= levels; ++level) {
    text += "l" + std::to_string(level) + ": &l" + std::to_string(level) + " [";
    for (int i = 0; i < fan_out; ++i) {
      text += (i ? ", *l" : "*l") + std::to_string(level - 1);
    }
    text += "]\n";
  }
  return text;
}

site_t ForgedSiteWithAliasBomb(int levels, int fan_out, const std::string& leaf,
                               const std::string& process) {
  return DemoSiteWith("", AliasBombText(levels, fan_out, leaf), process);
}

site_t ForgedSiteWithText(const std::string& site_text, const std::string& process) {
  return DemoSiteWith(site_text, "", process);
}

bool CopyLogWithSites(const std::string& from, const std::string& to,
                      const std::vector<site_t>& sites, std::string* error) {
  auto reader = LogReader::Open(from, error);
  if (reader == nullptr) return false;
  auto writer = LogWriter::Create(to, /*overwrite=*/true, error);
  if (writer == nullptr) return false;
  bool wrote_sites = false;
  LogEvent event;
  while (reader->Next(&event)) {
    if (!wrote_sites) {
      for (const site_t& site : sites) {
        std::vector<uint8_t> bytes(static_cast<size_t>(site.getEncodedSize()));
        site.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
        if (!writer->Write(event.utime, kSiteChannel, bytes.data(), static_cast<int>(bytes.size()),
                           error)) {
          return false;
        }
      }
      wrote_sites = true;
    }
    if (event.channel == kSiteChannel) continue;
    if (!writer->Write(event.utime, event.channel, event.data.data(),
                       static_cast<int>(event.data.size()), error)) {
      return false;
    }
  }
  return writer->Flush(error);
}

bool CopyLogWithSite(const std::string& from, const std::string& to, const site_t& site,
                     std::string* error) {
  return CopyLogWithSites(from, to, {site}, error);
}

site_t ForgedSiteWithLargeFiles(int variant, const std::string& process) {
  LoadedSite loaded;
  std::string error;
  if (!LoadSiteWithTexts(DemoSitePath(), &loaded, &error)) {
    throw std::runtime_error("demo site: " + error);
  }
  for (int i = 0; i < 15; ++i) {
    std::string text = "# variant " + std::to_string(variant) + "\n";
    text.resize(255 * 1024, 'x');
    loaded.texts.files["large_" + std::to_string(i) + ".yaml"] = std::move(text);
  }
  loaded.content_hash = SiteContentHash(loaded.texts);
  site_t msg;
  if (!MakeSiteMessage(loaded, process, 1700000000000000, &msg, &error)) {
    throw std::runtime_error("forged site: " + error);
  }
  return msg;
}

}  // namespace roomfix::testing
