#include "msgio/site_message.h"

#include <fmt/format.h>
#include <openssl/evp.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <iterator>
#include <map>
#include <mutex>
#include <set>
#include <string_view>
#include <utility>

#include "core/world/file_io.h"
#include "msgio/channels.h"
#include "msgio/log.h"
#include "msgio/process.h"
#include "msgio/time_limits.h"
#include "msgio/wire_check.h"

#ifndef ROOMFIX_VERSION
#define ROOMFIX_VERSION "unknown"
#endif

namespace roomfix {
namespace {

// As site.cc resolves cameras[].calibration: against the site file's folder.
std::string DirName(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

void AppendLengthPrefixed(std::string* out, const std::string& text) {
  *out += std::to_string(text.size());
  *out += '\n';
  *out += text;
}

std::string Sha256Hex(const std::string& bytes) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int length = 0;
  // EVP_Digest fails only on allocation failure inside OpenSSL; an empty
  // hash then never equals a real one, so nothing is silently accepted.
  if (EVP_Digest(bytes.data(), bytes.size(), digest, &length, EVP_sha256(), nullptr) != 1) {
    return "";
  }
  static const char kHex[] = "0123456789abcdef";
  std::string hex;
  for (unsigned int i = 0; i < length; ++i) {
    hex += kHex[digest[i] >> 4];
    hex += kHex[digest[i] & 15];
  }
  return hex;
}

std::string Who(const std::string& process, const std::string& host, int32_t pid) {
  std::string who = process.empty() ? "?" : process;
  if (!host.empty()) who += "@" + host;
  if (pid > 0) who += " (pid " + std::to_string(pid) + ")";
  return who;
}

// --- YAML difference by key path -------------------------------------------
//
// A SITE from the bus or a log is compared with --config key by key, and its
// texts are whatever a publisher wrote (a calibration of a flat map with tens
// of thousands of keys, anchors whose aliases expand a few bytes into a tree
// of millions of nodes, an alias inside its own anchor, which yaml-cpp
// resolves into a cycle). So the walk costs at most linear work in the texts'
// size whatever they hold:
// - a mapping's keys are looked up in an index of the other side's keys
//   (a sorted map: O(n log n) comparisons of keys, never yaml-cpp's
//   operator[], which scans the mapping and made the comparison quadratic);
// - every pair of nodes visited is paid from a budget of kVisitsPerByte per
//   byte of the two texts: text without anchors never exhausts it (a node
//   takes at least one byte, and a walk visits each node of either side at
//   most once), and expansions through aliases stop there;
// - nesting deeper than kMaxDepth (no site or calibration nests beyond 5;
//   a cycle nests forever) stops the walk too;
// - a key path is built only for the lines kept, from components clipped to
//   kShownBytes, so a long key costs its length once, not once per child.

constexpr int64_t kVisitsPerByte = 2;
constexpr int64_t kMinVisits = 64;
constexpr int kMaxDepth = 32;
constexpr size_t kShownBytes = 40;

std::string Clipped(const std::string& text) {
  return text.size() > kShownBytes ? text.substr(0, kShownBytes - 3) + "..." : text;
}

std::string Brief(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "absent";
  if (node.IsMap()) return "a mapping";
  if (node.IsSequence()) return "a list of " + std::to_string(node.size());
  return Clipped(node.Scalar());
}

bool ScalarsEqual(const std::string& a, const std::string& b) {
  if (a == b) return true;
  // Numbers compare by value: 2.50 and 2.5 are one receiver position.
  char* end_a = nullptr;
  char* end_b = nullptr;
  const double x = std::strtod(a.c_str(), &end_a);
  const double y = std::strtod(b.c_str(), &end_b);
  return !a.empty() && !b.empty() && *end_a == '\0' && *end_b == '\0' && x == y;
}

class YamlDiff {
 public:
  YamlDiff(std::string prefix, int64_t budget, size_t max_lines, SiteDiff* out)
      : prefix_(std::move(prefix)), budget_(budget), max_lines_(max_lines), out_(out) {}

  void Walk(const YAML::Node& a, const YAML::Node& b, int depth) {
    if (!Spend(depth)) return;
    const bool a_absent = !a.IsDefined() || a.IsNull();
    const bool b_absent = !b.IsDefined() || b.IsNull();
    if (a_absent && b_absent) return;
    if (a_absent || b_absent || a.Type() != b.Type()) return Report(a, b);
    if (a.IsMap()) return WalkMaps(a, b, depth);
    if (a.IsSequence()) return WalkSequences(a, b, depth);
    if (!ScalarsEqual(a.Scalar(), b.Scalar())) Report(a, b);
  }

 private:
  bool Spend(int depth) {
    if (out_->incomplete) return false;
    ++out_->nodes_visited;
    if (out_->nodes_visited > budget_ || depth > kMaxDepth) {
      out_->incomplete = true;
      return false;
    }
    return true;
  }

  void WalkMaps(const YAML::Node& a, const YAML::Node& b, int depth) {
    // By key text; a repeated key (refused in a site, possible in a
    // calibration a publisher did not parse) counts with its first value,
    // as yaml-cpp's own lookup would.
    std::map<std::string_view, YAML::Node> b_keys;
    for (const auto& kv : b) b_keys.emplace(kv.first.Scalar(), kv.second);
    std::set<std::string_view> a_keys;
    const YAML::Node absent(YAML::NodeType::Undefined);
    for (const auto& kv : a) {
      const std::string& k = kv.first.Scalar();
      if (!a_keys.insert(k).second) continue;
      const auto it = b_keys.find(k);
      path_.push_back(Clipped(k));
      Walk(kv.second, it == b_keys.end() ? absent : it->second, depth + 1);
      path_.pop_back();
      if (out_->incomplete) return;
    }
    for (const auto& kv : b) {
      const std::string& k = kv.first.Scalar();
      if (!a_keys.insert(k).second) continue;
      path_.push_back(Clipped(k));
      Walk(absent, kv.second, depth + 1);
      path_.pop_back();
      if (out_->incomplete) return;
    }
  }

  void WalkSequences(const YAML::Node& a, const YAML::Node& b, int depth) {
    const YAML::Node absent(YAML::NodeType::Undefined);
    auto ia = a.begin();
    auto ib = b.begin();
    for (size_t i = 0; ia != a.end() || ib != b.end(); ++i) {
      path_.push_back("[" + std::to_string(i) + "]");
      Walk(ia != a.end() ? YAML::Node(*ia) : absent, ib != b.end() ? YAML::Node(*ib) : absent,
           depth + 1);
      path_.pop_back();
      if (out_->incomplete) return;
      if (ia != a.end()) ++ia;
      if (ib != b.end()) ++ib;
    }
  }

  void Report(const YAML::Node& a, const YAML::Node& b) {
    ++out_->count;
    if (out_->lines.size() >= max_lines_) return;
    std::string path;
    for (const std::string& part : path_) {
      if (!path.empty() && part[0] != '[') path += '.';
      path += part;
    }
    out_->lines.push_back(prefix_ + (path.empty() ? "(document)" : path) + ": " + Brief(a) +
                          " -> " + Brief(b));
  }

  std::string prefix_;
  int64_t budget_;
  size_t max_lines_;
  SiteDiff* out_;
  std::vector<std::string> path_;
};

// Texts that passed ParseSite or came from a file; a text that is not YAML
// (a calibration the publisher could not parse) differs as a whole.
void DiffTexts(const std::string& a, const std::string& b, const std::string& prefix,
               size_t max_lines, SiteDiff* out) {
  if (a == b || out->incomplete) return;
  const int64_t budget =
      out->nodes_visited + kMinVisits + kVisitsPerByte * static_cast<int64_t>(a.size() + b.size());
  try {
    const YAML::Node root_a = YAML::Load(a);
    const YAML::Node root_b = YAML::Load(b);
    YamlDiff(prefix, budget, max_lines, out).Walk(root_a, root_b, 0);
  } catch (const YAML::Exception&) {
    ++out->count;
    if (out->lines.size() < max_lines) out->lines.push_back(prefix + "(text differs; not YAML)");
  }
}

// --- the process's site -----------------------------------------------------

std::mutex g_site_mutex;
std::shared_ptr<const site_t> g_site;
SitePublishSchedule g_site_schedule;

}  // namespace

std::string RoomfixVersion() { return ROOMFIX_VERSION; }

std::string SiteContentHash(const SiteTexts& texts) {
  std::string bytes = "roomfix site v1\n";
  AppendLengthPrefixed(&bytes, texts.site_text);
  for (const auto& [name, text] : texts.files) {  // std::map: sorted by name
    AppendLengthPrefixed(&bytes, name);
    AppendLengthPrefixed(&bytes, text);
  }
  return Sha256Hex(bytes);
}

int64_t SiteHashCounterValue(const std::string& content_hash) {
  if (content_hash.size() < 15) return -1;
  int64_t value = 0;
  for (size_t i = 0; i < 15; ++i) {
    const char c = content_hash[i];
    int digit = -1;
    if (c >= '0' && c <= '9') digit = c - '0';
    if (c >= 'a' && c <= 'f') digit = c - 'a' + 10;
    if (digit < 0) return -1;
    value = value * 16 + digit;
  }
  return value;
}

std::string SiteHashCounterText(int64_t value) {
  return fmt::format("{:015x}", static_cast<unsigned long long>(value));
}

std::string ShortSiteHash(const std::string& content_hash) { return content_hash.substr(0, 12); }

bool LoadSiteWithTexts(const std::string& path, LoadedSite* out, std::string* error) {
  LoadedSite loaded;
  if (!ReadConfigFile(path, &loaded.texts.site_text, error)) return false;
  if (!ParseSite(loaded.texts.site_text, path, DirName(path), &loaded.site, error)) return false;
  loaded.site.path = path;
  loaded.texts.site_path = path;
  // The names as written (no folder to resolve against) key the texts, so a
  // reader resolves them to the texts without any folder.
  Site as_written;
  if (!ParseSite(loaded.texts.site_text, path, "", &as_written, error)) return false;
  for (size_t i = 0; i < loaded.site.cameras.size(); ++i) {
    const std::string& name = as_written.cameras[i].calibration_file;
    if (name.empty() || loaded.texts.files.count(name) > 0) continue;
    std::string text;
    std::string why;
    if (ReadConfigFile(loaded.site.cameras[i].calibration_file, &text, &why)) {
      loaded.texts.files[name] = std::move(text);
    } else {
      loaded.texts.missing.push_back(name + " (" + why + ")");
    }
  }
  loaded.content_hash = SiteContentHash(loaded.texts);
  *out = std::move(loaded);
  return true;
}

bool MakeSiteMessage(const LoadedSite& loaded, const std::string& process, int64_t utime,
                     site_t* msg, std::string* error) {
  const auto over = [&](const std::string& what, size_t bytes, int32_t cap) {
    if (bytes < static_cast<size_t>(cap)) return false;
    *error = what + " is " + ByteSizeText(bytes) + ", over the " +
             ByteSizeText(static_cast<size_t>(cap) - 1) + " a site_t carries";
    return true;
  };
  if (over("the site file " + loaded.texts.site_path, loaded.texts.site_text.size(),
           wire_cap::kSiteTextBytes)) {
    return false;
  }
  if (loaded.texts.files.size() > static_cast<size_t>(wire_cap::kSiteFiles)) {
    *error = "the site names " + std::to_string(loaded.texts.files.size()) +
             " calibration files, over the " + std::to_string(wire_cap::kSiteFiles) +
             " a site_t carries";
    return false;
  }
  site_t m{};
  m.utime = utime;
  for (const auto& [name, text] : loaded.texts.files) {
    if (over("calibration file " + name, text.size(), wire_cap::kSiteFileBytes) ||
        over("the name " + name, name.size(), wire_cap::kPathBytes)) {
      return false;
    }
    site_file_t f{};
    f.name = name;
    f.text = text;
    m.files.push_back(std::move(f));
  }
  m.num_files = static_cast<int32_t>(m.files.size());
  m.site_text = loaded.texts.site_text;
  // Informative fields are clipped to their caps rather than refused.
  const auto clip = [](std::string text, int32_t cap) {
    if (text.size() >= static_cast<size_t>(cap)) text.resize(static_cast<size_t>(cap) - 1);
    return text;
  };
  m.site_name = clip(loaded.site.name, wire_cap::kNameBytes);
  m.site_path = clip(loaded.texts.site_path, wire_cap::kPathBytes);
  std::string missing;
  for (const auto& line : loaded.texts.missing) missing += (missing.empty() ? "" : "\n") + line;
  m.missing = clip(missing, wire_cap::kPathBytes);
  m.content_hash = loaded.content_hash;
  m.roomfix_version = clip(RoomfixVersion(), wire_cap::kVersionBytes);
  m.process = clip(process, wire_cap::kNameBytes);
  char host[256] = {0};
  if (::gethostname(host, sizeof(host) - 1) == 0) m.host = clip(host, wire_cap::kNameBytes);
  m.pid = static_cast<int32_t>(::getpid());
  *msg = std::move(m);
  return true;
}

namespace {
// LoadSiteFromMessage, with the refusal's reason for the counters:
// "over_cap", "duplicate_file", "hash_mismatch" or "invalid_site".
bool LoadFromMessage(const site_t& msg, const std::string& origin, LoadedSite* out,
                     std::string* error, std::string* reason) {
  LoadedSite loaded;
  // The same cap as a site file read from disk (the wire cap is lower; this
  // holds for a site_t that did not come through DecodeChecked).
  if (msg.site_text.size() > kConfigFileCapBytes) {
    *error = origin + ": site text of " + ByteSizeText(msg.site_text.size()) + " is over the " +
             ByteSizeText(kConfigFileCapBytes) + " cap for configuration files";
    *reason = "over_cap";
    return false;
  }
  loaded.texts.site_text = msg.site_text;
  loaded.texts.site_path = msg.site_path;
  for (const auto& f : msg.files) {
    if (f.text.size() > kConfigFileCapBytes) {
      *error = origin + ": file '" + f.name + "' is over the " + ByteSizeText(kConfigFileCapBytes) +
               " cap for configuration files";
      *reason = "over_cap";
      return false;
    }
    if (!loaded.texts.files.emplace(f.name, f.text).second) {
      *error = origin + ": file '" + f.name + "' carried twice";
      *reason = "duplicate_file";
      return false;
    }
  }
  const std::string hash = SiteContentHash(loaded.texts);
  if (hash != msg.content_hash) {
    *error = origin + ": content_hash " + ShortSiteHash(msg.content_hash) +
             " does not match the texts carried (" + ShortSiteHash(hash) + ")";
    *reason = "hash_mismatch";
    return false;
  }
  // No folder: calibration names stay as written and key loaded.texts.files.
  if (!ParseSite(msg.site_text, origin, "", &loaded.site, error)) {
    *reason = "invalid_site";
    return false;
  }
  loaded.site.path.clear();
  if (!msg.missing.empty()) {
    size_t start = 0;
    while (start <= msg.missing.size()) {
      const size_t end = msg.missing.find('\n', start);
      loaded.texts.missing.push_back(msg.missing.substr(start, end - start));
      if (end == std::string::npos) break;
      start = end + 1;
    }
  }
  loaded.content_hash = hash;
  loaded.roomfix_version = msg.roomfix_version;
  loaded.process = msg.process;
  loaded.host = msg.host;
  loaded.pid = msg.pid;
  loaded.utime = msg.utime;
  *out = std::move(loaded);
  return true;
}
}  // namespace

bool LoadSiteFromMessage(const site_t& msg, const std::string& origin, LoadedSite* out,
                         std::string* error) {
  std::string reason;
  return LoadFromMessage(msg, origin, out, error, &reason);
}

const std::string* SiteCalibrationText(const LoadedSite& loaded, size_t camera_index) {
  if (camera_index >= loaded.site.cameras.size()) return nullptr;
  const std::string& file = loaded.site.cameras[camera_index].calibration_file;
  if (file.empty()) return nullptr;
  // A site loaded from a file has the name resolved against its folder; the
  // texts are keyed by the name as written, which that path ends with.
  auto it = loaded.texts.files.find(file);
  if (it != loaded.texts.files.end()) return &it->second;
  const std::string folder = DirName(loaded.texts.site_path) + "/";
  if (file.rfind(folder, 0) == 0) {
    it = loaded.texts.files.find(file.substr(folder.size()));
    if (it != loaded.texts.files.end()) return &it->second;
  }
  return nullptr;
}

namespace {
std::atomic<int64_t> g_site_comparison_nodes{0};
}  // namespace

int64_t SiteComparisonNodesVisited() { return g_site_comparison_nodes.load(); }

SiteDiff CompareSiteTexts(const SiteTexts& a, const SiteTexts& b, size_t max_lines) {
  SiteDiff out;
  DiffTexts(a.site_text, b.site_text, "", max_lines, &out);
  std::set<std::string> names;
  for (const auto& kv : a.files) names.insert(kv.first);
  for (const auto& kv : b.files) names.insert(kv.first);
  for (const std::string& name : names) {
    const auto ia = a.files.find(name);
    const auto ib = b.files.find(name);
    const std::string prefix = "calibration '" + Clipped(name) + "' ";
    if (ia == a.files.end() || ib == b.files.end()) {
      ++out.count;
      if (out.lines.size() < max_lines) {
        out.lines.push_back(prefix +
                            (ia == a.files.end() ? "absent -> present" : "present -> absent"));
      }
      continue;
    }
    DiffTexts(ia->second, ib->second, prefix, max_lines, &out);
  }
  g_site_comparison_nodes += out.nodes_visited;
  return out;
}

std::vector<std::string> SiteDifferences(const SiteTexts& a, const SiteTexts& b) {
  return CompareSiteTexts(a, b).lines;
}

std::string SiteMismatchWarning(const LoadedSite& a, const std::string& what_a, const LoadedSite& b,
                                const std::string& what_b, size_t max_keys) {
  if (a.content_hash == b.content_hash) return "";
  const SiteDiff diff = CompareSiteTexts(a.texts, b.texts, max_keys);
  std::string line = what_a + " (" + ShortSiteHash(a.content_hash) + ") and " + what_b + " (" +
                     ShortSiteHash(b.content_hash) + ") differ";
  if (diff.count == 0 && !diff.incomplete) return line + " only in layout or comments";
  line += " at " + std::to_string(diff.count) + (diff.incomplete ? " or more" : "") +
          (diff.count == 1 && !diff.incomplete ? " key: " : " keys: ");
  for (size_t i = 0; i < diff.lines.size(); ++i) line += (i ? "; " : "") + diff.lines[i];
  if (diff.count > diff.lines.size()) {
    line += "; and " + std::to_string(diff.count - diff.lines.size()) + " more";
  }
  if (diff.incomplete) {
    line += " (compared " + std::to_string(diff.nodes_visited) +
            " nodes and stopped: aliases expand the texts beyond their size, or they nest deeper "
            "than a site does)";
  }
  return line;
}

void SiteHashTracker::Expire() {
  for (auto it = by_process_.begin(); it != by_process_.end();) {
    it = SaturatingDifferenceUs(latest_utime_, it->second.last_utime) > kSiteExpiryUs
             ? by_process_.erase(it)
             : std::next(it);
  }
  if (SaturatingDifferenceUs(latest_utime_, last_unlisted_utime_) > kSiteExpiryUs) {
    last_unlisted_utime_ = INT64_MIN;
  }
}

void SiteHashTracker::Observe(const std::string& hash15, const std::string& who,
                              int64_t recv_utime) {
  latest_utime_ = std::max(latest_utime_, recv_utime);
  Expire();
  // Bounded: anyone on the bus can invent names.
  auto it = by_process_.find(who);
  if (it == by_process_.end()) {
    if (by_process_.size() >= kMaxProcesses) {
      last_unlisted_utime_ = std::max(last_unlisted_utime_, recv_utime);
      return;
    }
    it = by_process_.emplace(who, Stated{}).first;
  }
  it->second.hash15 = hash15;
  it->second.last_utime = std::max(it->second.last_utime, recv_utime);
}

void SiteHashTracker::ObserveSite(const site_t& msg, int64_t recv_utime) {
  const int64_t value = SiteHashCounterValue(msg.content_hash);
  if (value < 0) return;
  Observe(SiteHashCounterText(value), Who(msg.process, msg.host, 0), recv_utime);
}

void SiteHashTracker::ObserveStatus(const process_status_t& msg, int64_t recv_utime) {
  for (const auto& c : msg.counters) {
    if (c.name == kSiteHashCounter && c.count >= 0) {
      Observe(SiteHashCounterText(c.count), Who(msg.process, msg.host, 0), recv_utime);
    }
  }
}

size_t SiteHashTracker::distinct_hashes() const {
  std::set<std::string> hashes;
  for (const auto& [who, stated] : by_process_) hashes.insert(stated.hash15);
  return hashes.size() + (last_unlisted_utime_ != INT64_MIN ? 1 : 0);
}

std::string SiteHashTracker::Disagreement() const {
  std::map<std::string, std::vector<std::string>> by_hash;
  for (const auto& [who, stated] : by_process_) by_hash[stated.hash15].push_back(who);
  if (by_hash.size() < 2) return "";
  std::string line = "processes disagree on the site:";
  bool first = true;
  for (const auto& [hash, who] : by_hash) {
    line += first ? " " : "; ";
    first = false;
    line += hash.substr(0, 12) + " by ";
    for (size_t i = 0; i < who.size(); ++i) line += (i ? ", " : "") + who[i];
  }
  if (last_unlisted_utime_ != INT64_MIN) line += "; and further processes not listed";
  return line;
}

void SiteListing::ObserveSite(const site_t& msg, int64_t recv_utime,
                              std::vector<std::string>* lines) {
  if (listed_.count(msg.content_hash) == 0) {
    if (listed_.size() >= kMaxListed) {
      // A flood of invented hashes: said once, then only counted.
      if (not_listed_++ == 0) {
        lines->push_back("warning: " + std::to_string(kMaxListed) +
                         " sites listed; further sites on SITE are counted, not described");
      }
      Disagreement(lines);
      return;
    }
    LoadedSite site;
    std::string detail;
    if (!LoadSiteFromMessage(msg, "SITE from " + msg.process, &site, &detail)) {
      // Not listed: the real site with this hash is still described when
      // it comes. A flood is counted; the first few are said.
      if (refused_++ < 8) lines->push_back("warning: site refused: " + detail);
      return;
    }
    listed_.insert(msg.content_hash);
    lines->push_back("site on SITE: " + DescribeSite(site));
    if (config_ != nullptr) {
      const std::string mismatch =
          SiteMismatchWarning(*config_, "--config", site, "SITE from " + msg.process);
      if (!mismatch.empty()) lines->push_back("warning: " + mismatch);
    }
  }
  tracker_.ObserveSite(msg, recv_utime);
  Disagreement(lines);
}

void SiteListing::ObserveStatus(const process_status_t& msg, int64_t recv_utime,
                                std::vector<std::string>* lines) {
  tracker_.ObserveStatus(msg, recv_utime);
  Disagreement(lines);
}

void SiteListing::Disagreement(std::vector<std::string>* lines) {
  const std::string line = tracker_.Disagreement();
  if (line == last_warning_) return;
  last_warning_ = line;
  if (!line.empty()) lines->push_back("warning: " + line);
}

namespace {

// What a verified SITE message carried beside its hashed texts: a repeat
// with the same hash, these and texts that hash alike is the same message.
// Kept instead of the message (up to 5 MiB of texts each: 16 of them cost
// `compare` 80 MB, issue #28).
struct VerifiedSite {
  std::string site_path;
  std::string missing;
};

// The content hash of the texts a message carries, as SiteContentHash; ""
// when a file name repeats (LoadSiteFromMessage refuses that).
std::string HashOfCarriedTexts(const site_t& msg) {
  SiteTexts texts;
  texts.site_text = msg.site_text;
  for (const auto& f : msg.files) {
    if (!texts.files.emplace(f.name, f.text).second) return "";
  }
  return SiteContentHash(texts);
}

}  // namespace

bool ReadSiteFromLog(const std::string& log_path, SiteFromLog* out, std::string* error) {
  auto reader = LogReader::Open(log_path, error);
  if (reader == nullptr) return false;
  SiteFromLog result;
  SiteHashTracker tracker;
  // By content hash: what the first verified message carried, for skipping
  // repeats; one small entry per distinct site (bounded by the log's size).
  std::map<std::string, VerifiedSite> verified;
  LogEvent event;
  while (reader->Next(&event)) {
    const bool is_site = event.channel == kSiteChannel;
    if (!is_site && event.channel != kStatusChannel) continue;
    const int size = static_cast<int>(event.data.size());
    if (!is_site) {
      process_status_t status;
      if (DecodeChecked(event.data.data(), size, &status, nullptr)) {
        tracker.ObserveStatus(status, event.utime);
      }
      continue;
    }
    const auto refuse = [&](const std::string& reason, const std::string& detail) {
      ++result.refused;
      ++result.refused_by_reason[reason];
      if (result.first_refusal.empty()) {
        result.first_refusal = "event " + std::to_string(event.eventnum) + ": " + detail;
      }
    };
    site_t msg;
    std::string reason;
    std::string detail;
    if (!DecodeChecked(event.data.data(), size, &msg, &reason, &detail)) {
      refuse(reason, detail);
      continue;
    }
    const std::string who = Who(msg.process, msg.host, 0);
    // A repeat of a verified message (same hash, same texts) is valid as
    // that one was: its texts are hashed again (SHA-256, linear and fast),
    // not parsed again.
    const auto verified_it = verified.find(msg.content_hash);
    if (verified_it != verified.end() && verified_it->second.site_path == msg.site_path &&
        verified_it->second.missing == msg.missing && HashOfCarriedTexts(msg) == msg.content_hash) {
      ++result.repeats_not_reparsed;
    } else {
      const std::string origin = log_path + ": SITE from " + Who(msg.process, msg.host, msg.pid);
      LoadedSite loaded;
      std::string why;
      if (!LoadFromMessage(msg, origin, &loaded, &why, &reason)) {
        refuse(reason, why);
        continue;
      }
      verified.emplace(msg.content_hash, VerifiedSite{msg.site_path, msg.missing});
      if (result.accepted == 0) {
        result.site = std::move(loaded);
        result.event_utime = event.utime;
      }
    }
    ++result.accepted;
    tracker.ObserveSite(msg, event.utime);
    auto hash_it = result.publishers_by_hash.find(msg.content_hash);
    if (hash_it == result.publishers_by_hash.end() &&
        result.publishers_by_hash.size() < SiteFromLog::kMaxSiteHashes) {
      hash_it = result.publishers_by_hash.emplace(msg.content_hash, std::set<std::string>()).first;
    }
    if (hash_it != result.publishers_by_hash.end() && hash_it->second.size() < 16) {
      hash_it->second.insert(who);
    }
  }
  result.disagreement = tracker.Disagreement();
  result.distinct_sites = static_cast<int64_t>(verified.size());
  if (result.accepted == 0) {
    *error = log_path + " holds no SITE message";
    if (result.refused > 0) {
      *error += " that passes: " + std::to_string(result.refused) + " refused (" +
                RefusalCounts(result.refused_by_reason) + "); first " + result.first_refusal;
    } else {
      *error += " (recorded before processes published their site, or without the SITE channel)";
    }
    *error += "; give the site file with --config";
    *out = std::move(result);
    return false;
  }
  *out = std::move(result);
  return true;
}

std::string DescribeSite(const LoadedSite& loaded) {
  std::string line = loaded.site.name + ", hash " + ShortSiteHash(loaded.content_hash);
  if (!loaded.process.empty()) {
    line += ", roomfix " + (loaded.roomfix_version.empty() ? "?" : loaded.roomfix_version) +
            ", published by " + Who(loaded.process, loaded.host, loaded.pid);
    if (!loaded.texts.site_path.empty()) line += " from " + loaded.texts.site_path;
  } else {
    line += ", file " + loaded.texts.site_path;
  }
  if (!loaded.texts.missing.empty()) {
    line +=
        "; calibration files missing at the source: " + std::to_string(loaded.texts.missing.size());
  }
  return line;
}

ToolSite ResolveToolSite(const std::string& config_path, const std::string& log_path) {
  ToolSite s;
  s.source = config_path.empty() ? "log" : "--config";
  // Told apart from a log without SITE: a bad --config stops every tool.
  if (!config_path.empty() && !LoadSiteWithTexts(config_path, &s.site, &s.error)) {
    s.config_failed = true;
    return s;
  }
  SiteFromLog from_log;
  std::string log_error;
  const bool log_has_site = !log_path.empty() && ReadSiteFromLog(log_path, &from_log, &log_error);
  if (!log_path.empty()) {
    if (from_log.refused > 0) {
      s.warnings.push_back(log_path + ": " + std::to_string(from_log.refused) +
                           " SITE messages refused (" + RefusalCounts(from_log.refused_by_reason) +
                           "); first " + from_log.first_refusal);
    }
    if (!from_log.disagreement.empty()) {
      s.warnings.push_back(log_path + ": " + from_log.disagreement);
    }
  }
  if (config_path.empty()) {
    if (!log_has_site) {
      s.error = log_path.empty() ? "no site: give --config" : log_error;
      return s;
    }
    if (from_log.distinct_sites > 1) {
      s.error = log_path + " holds SITE messages of " + std::to_string(from_log.distinct_sites) +
                " different sites";
      if (from_log.distinct_sites > static_cast<int64_t>(from_log.publishers_by_hash.size())) {
        s.error += " (the first " + std::to_string(from_log.publishers_by_hash.size()) + " named)";
      }
      s.error += ":";
      bool first = true;
      for (const auto& [hash, who] : from_log.publishers_by_hash) {
        s.error += (first ? " " : "; ") + ShortSiteHash(hash) + " by ";
        first = false;
        bool first_who = true;
        for (const std::string& w : who) {
          s.error += (first_who ? "" : ", ") + w;
          first_who = false;
        }
      }
      s.error += "; give the site file with --config";
      return s;
    }
    s.site = std::move(from_log.site);
    s.line = "site from " + log_path + ": " + DescribeSite(s.site);
    s.known = true;
    return s;
  }
  s.line = "site from --config " + config_path + ": " + DescribeSite(s.site);
  if (log_has_site) {
    const std::string mismatch = SiteMismatchWarning(from_log.site, "the site in " + log_path,
                                                     s.site, "--config " + config_path);
    if (!mismatch.empty()) s.warnings.push_back(mismatch);
  }
  s.known = true;
  return s;
}

// --- when to publish ---------------------------------------------------------

void SitePublishSchedule::Reset(const site_t& own) {
  self_ = Identity(own.process, own.host, own.pid);
  hash_ = own.content_hash;
  last_publish_utime_ = -1;
  smaller_heard_utime_ = INT64_MIN;
  newcomer_pending_ = false;
  last_reason_ = "";
}

bool SitePublishSchedule::WorthVerifying(const site_t& msg, int64_t recv_utime) const {
  if (msg.content_hash != hash_) return false;
  if (!(Identity(msg.process, msg.host, msg.pid) < self_)) return false;
  return smaller_heard_utime_ == INT64_MIN || recv_utime - smaller_heard_utime_ >= kSiteAnswerGapUs;
}

void SitePublishSchedule::ObserveSite(const site_t& msg, int64_t recv_utime) {
  if (msg.content_hash != hash_) return;
  if (!(Identity(msg.process, msg.host, msg.pid) < self_)) return;
  smaller_heard_utime_ = std::max(smaller_heard_utime_, recv_utime);
}

void SitePublishSchedule::ObserveStatus(const process_status_t& msg, int64_t recv_utime) {
  const Identity who(msg.process, msg.host, msg.pid);
  if (who == self_) return;
  auto it = peers_.find(who);
  if (it == peers_.end()) {
    if (peers_.size() >= kMaxPeers) {
      auto oldest = peers_.begin();
      for (auto p = peers_.begin(); p != peers_.end(); ++p) {
        if (p->second < oldest->second) oldest = p;
      }
      peers_.erase(oldest);
    }
    peers_.emplace(who, recv_utime);
    newcomer_pending_ = true;
    return;
  }
  // Time going backwards (a log replayed twice) is no return.
  if (recv_utime - it->second > kNewcomerAfterUs) newcomer_pending_ = true;
  it->second = std::max(it->second, recv_utime);
}

bool SitePublishSchedule::elected(int64_t now_utime) const {
  return smaller_heard_utime_ == INT64_MIN ||
         now_utime - smaller_heard_utime_ > kSiteElectionWindowUs ||
         now_utime < smaller_heard_utime_ - kSiteElectionWindowUs;
}

bool SitePublishSchedule::Due(int64_t now_utime) {
  const char* reason = nullptr;
  if (last_publish_utime_ < 0) {
    reason = "start";
  } else if (elected(now_utime)) {
    const int64_t since = now_utime - last_publish_utime_;
    if (since >= kSitePeriodUs || since < 0) {
      reason = "period";
    } else if (newcomer_pending_ && since >= kSiteAnswerGapUs) {
      reason = "newcomer";
    }
  }
  if (reason == nullptr) return false;
  last_publish_utime_ = now_utime;
  newcomer_pending_ = false;
  last_reason_ = reason;
  return true;
}

// --- the process's site -------------------------------------------------------

void SetProcessSite(std::shared_ptr<const site_t> msg) {
  std::lock_guard<std::mutex> lock(g_site_mutex);
  g_site = std::move(msg);
  g_site_schedule.Reset(g_site != nullptr ? *g_site : site_t{});
}

std::shared_ptr<const site_t> ProcessSite() {
  std::lock_guard<std::mutex> lock(g_site_mutex);
  return g_site;
}

bool MaybePublishProcessSite(Bus* bus, int64_t now_utime) {
  std::shared_ptr<const site_t> site;
  {
    std::lock_guard<std::mutex> lock(g_site_mutex);
    if (g_site == nullptr || !g_site_schedule.Due(now_utime)) return false;
    site = g_site;
  }
  site_t msg = *site;
  msg.utime = now_utime;
  return bus->Publish(kSiteChannel, msg);
}

void FollowSitePeers(Bus* bus) {
  bus->Subscribe<site_t>(kSiteChannel, [](const site_t& msg, const MessageInfo& info) {
    {
      std::lock_guard<std::mutex> lock(g_site_mutex);
      if (!g_site_schedule.WorthVerifying(msg, info.recv_utime)) return;
    }
    // Hashing the texts (linear in their size) outside the lock: a SITE of
    // another process counts only when its texts are what it claims.
    if (HashOfCarriedTexts(msg) != msg.content_hash) return;
    std::lock_guard<std::mutex> lock(g_site_mutex);
    g_site_schedule.ObserveSite(msg, info.recv_utime);
  });
  bus->Subscribe<process_status_t>(kStatusChannel,
                                   [](const process_status_t& msg, const MessageInfo& info) {
                                     std::lock_guard<std::mutex> lock(g_site_mutex);
                                     g_site_schedule.ObserveStatus(msg, info.recv_utime);
                                   });
}

}  // namespace roomfix
