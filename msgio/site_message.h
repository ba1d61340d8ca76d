#ifndef ROOMFIX_MSGIO_SITE_MESSAGE_H_
#define ROOMFIX_MSGIO_SITE_MESSAGE_H_

// The site travels with the data: every process that loads a site publishes
// it as a site_t on SITE (its text, its calibration files' texts, their
// SHA-256), at start, and one process per site every kSitePeriodUs
// (SitePublishSchedule), and states the hash in STATUS
// (the `site_hash` counter). Tools reading a log take the site from there when
// no --config is given (docs/messages.md, docs/site_file.md).
//
// A site_t from a bus or a log is outside input: it is decoded only with
// DecodeChecked, and its texts go through exactly the checks a site file
// does (ReadConfigFile's size cap, ParseSite: YAML syntax, duplicated keys,
// every validation rule), plus the hash, which must match the texts.
// Calibration files the site names resolve to the texts the message
// carries, never to files on disk.

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/channels.h"
#include "roomfix/process_status_t.hpp"
#include "roomfix/site_t.hpp"

namespace roomfix {

// How often the process elected for a site republishes it: a log started
// (or a logger restarted) mid-run holds a SITE within this long. One site of
// a few kB every 5 s is about 2 % of a demo log (docs/messages.md).
inline constexpr int64_t kSitePeriodUs = 5000000;
// The STATUS counter (a gauge, StatusReporter::SetCounter) holding the first
// 60 bits of the site's SHA-256: the first 15 hex digits of content_hash read
// as one number. Carried as a counter so process_status_t, its fingerprint
// and every recorded log keep working (docs/messages.md says why).
inline constexpr char kSiteHashCounter[] = "site_hash";

// The texts a site is made of. `files` are the calibration files the
// cameras name, by the name as the site file writes it, without repeats;
// `missing` are names whose files could not be read (with the reason), which
// the process runs without (only camera_proc needs them, and refuses then).
struct SiteTexts {
  std::string site_path;
  std::string site_text;
  std::map<std::string, std::string> files;
  std::vector<std::string> missing;
};

// A site with the texts it was loaded from and where it came from.
struct LoadedSite {
  Site site;
  SiteTexts texts;
  // SiteContentHash(texts): 64 lower-case hex digits.
  std::string content_hash;
  // From a site_t only (empty or 0 for a file): the publisher and its
  // version, and the message's utime.
  std::string roomfix_version;
  std::string process;
  std::string host;
  int32_t pid = 0;
  int64_t utime = 0;
};

// This build's version (CMake PROJECT_VERSION).
std::string RoomfixVersion();

// SHA-256 over the site text and the files (sorted by name), each length-
// prefixed so that no two different sets of texts hash alike by moving bytes
// between them. 64 lower-case hex digits.
std::string SiteContentHash(const SiteTexts& texts);
// The first 15 hex digits of a content hash as the non-negative number the
// STATUS `site_hash` counter holds; -1 for a malformed hash.
int64_t SiteHashCounterValue(const std::string& content_hash);
// The counter value back as 15 hex digits (to compare with a content_hash's
// start, and for messages).
std::string SiteHashCounterText(int64_t value);
// The short form people see: the first 12 hex digits.
std::string ShortSiteHash(const std::string& content_hash);

// Loads a site file as LoadSite does (same checks, same error lines) and
// reads the calibration files its cameras name (resolved against the site's
// folder, through ReadConfigFile).
bool LoadSiteWithTexts(const std::string& path, LoadedSite* out, std::string* error);

// The message for a loaded site, published by `process` at `utime`. False
// with a one-line reason when a text is over its wire cap (site text 1 MiB,
// a file 256 KiB, 16 files; docs/messages.md): a receiver would refuse it.
bool MakeSiteMessage(const LoadedSite& loaded, const std::string& process, int64_t utime,
                     site_t* msg, std::string* error);

// The site a site_t carries, through the same checks as a site file (size
// cap, YAML, duplicated keys, validation) plus: the content hash matches the
// texts, file names are unique. `origin` names the message in errors and
// becomes the site's name for messages ("demo.lcm: SITE from trilat_proc").
// False with one line.
bool LoadSiteFromMessage(const site_t& msg, const std::string& origin, LoadedSite* out,
                         std::string* error);

// The text of the calibration a camera of a loaded site names, from the
// texts loaded with it (never from disk), or nullptr when the site carries
// none (the camera names none, or its file was missing at the publisher).
// Parse it with calib::ParseCalibration(*text, name, ...).
const std::string* SiteCalibrationText(const LoadedSite& loaded, size_t camera_index);

// The keys at which two sites differ, as key paths ("receivers[2].position_m[0]:
// 2.5 -> 2.55", "cameras[0].calibration file 'x.yaml': intrinsics.fx_px: ...").
// Both site texts are parsed as YAML and compared key by key (numbers
// numerically, so 2.50 equals 2.5); the calibration files carried are
// compared the same way by name.
//
// A site from the bus or a log holds whatever its publisher wrote, so the
// comparison costs at most linear work in the texts' size: keys are matched
// through an index (O(n log n)), and at most 2 YAML nodes per byte of the
// two texts (plus 64) are visited, and at most 32 levels deep: only anchors
// whose aliases expand a text beyond its size, or a cycle (an alias inside
// its own anchor), reach either limit, and the comparison then stops
// (`incomplete`). Key components and values are shown clipped to 40 bytes.
struct SiteDiff {
  // The first max_lines differences, in document order.
  std::vector<std::string> lines;
  // Every difference found; lines holds the first of them.
  size_t count = 0;
  // The visit budget or the depth limit stopped the comparison: count is
  // then a lower bound.
  bool incomplete = false;
  // Pairs of YAML nodes visited: the work done.
  int64_t nodes_visited = 0;
};
SiteDiff CompareSiteTexts(const SiteTexts& a, const SiteTexts& b, size_t max_lines = 64);
// The node pairs every CompareSiteTexts of this process has visited: the
// work tools and processes spent comparing sites (tests bound it against the
// texts' size; one counter for the process, safe from any thread).
int64_t SiteComparisonNodesVisited();
// CompareSiteTexts(a, b).lines: the first 64 differences. Empty when they agree.
std::vector<std::string> SiteDifferences(const SiteTexts& a, const SiteTexts& b);
// One warning line for two sites: "" when the hashes are equal, otherwise
// "<what_a> and <what_b> differ at N keys: k1, k2, ... (and M more)" (with
// "N or more" and why when the comparison stopped).
std::string SiteMismatchWarning(const LoadedSite& a, const std::string& what_a, const LoadedSite& b,
                                const std::string& what_b, size_t max_keys = 8);

// Which site each process states, from SITE messages and STATUS `site_hash`
// counters: processes disagree when two of them state different hashes
// (compared on the 15 hex digits STATUS carries). Each process (name and
// host) counts with the latest hash it stated, so a process restarted with a
// corrected site stops the disagreement at its next SITE or STATUS; one not
// heard from for kSiteExpiryUs (stopped, or gone with its old site) is
// forgotten. Time is the caller's: the receive time of the message (the log
// event's time in a log), never the wall clock, so log tools stay
// deterministic; time that goes backwards does not expire anything.
class SiteHashTracker {
 public:
  void ObserveSite(const site_t& msg, int64_t recv_utime);
  void ObserveStatus(const process_status_t& msg, int64_t recv_utime);
  // "" when the processes heard within kSiteExpiryUs state at most one
  // hash; otherwise one line naming each hash and who stated it:
  // "processes disagree on the site: 1a2b3c4d5e6f by trilat_proc@lab-pc;
  // 9f8e7d6c5b4a by fusion_proc@lab-pc2".
  std::string Disagreement() const;
  size_t distinct_hashes() const;

  // Three SITE periods: a live process publishes its STATUS every second
  // (and its site at start, and every kSitePeriodUs when elected), so one
  // missing for three periods has stopped.
  static constexpr int64_t kSiteExpiryUs = 3 * kSitePeriodUs;
  // At most this many processes are tracked (a flood of invented names must
  // not grow memory); further ones are counted as unlisted until they expire.
  static constexpr size_t kMaxProcesses = 64;

 private:
  struct Stated {
    std::string hash15;
    int64_t last_utime = 0;
  };
  void Observe(const std::string& hash15, const std::string& who, int64_t recv_utime);
  void Expire();
  std::map<std::string, Stated> by_process_;
  int64_t latest_utime_ = INT64_MIN;
  int64_t last_unlisted_utime_ = INT64_MIN;
};

// `roomfix listen`'s view of the SITE channel: describes each verified site
// once, compares it with --config, and follows which process states which
// hash. A hash is listed only after LoadSiteFromMessage verified the message
// (its texts hash to it and form a valid site), so a forged SITE carrying
// the real hash with other texts is refused and counted and does not hide
// the real one when it comes. At most kMaxListed sites are described; the
// first one over says so once, the rest are counted. Lines to print go to
// *lines (without the "roomfix listen: " prefix).
class SiteListing {
 public:
  static constexpr size_t kMaxListed = 64;
  // `config` may be null (no --config).
  explicit SiteListing(const LoadedSite* config) : config_(config) {}
  void ObserveSite(const site_t& msg, int64_t recv_utime, std::vector<std::string>* lines);
  void ObserveStatus(const process_status_t& msg, int64_t recv_utime,
                     std::vector<std::string>* lines);
  int64_t refused() const { return refused_; }
  int64_t not_listed() const { return not_listed_; }
  size_t listed() const { return listed_.size(); }

 private:
  void Disagreement(std::vector<std::string>* lines);
  const LoadedSite* config_;
  std::set<std::string> listed_;
  int64_t refused_ = 0;
  int64_t not_listed_ = 0;
  SiteHashTracker tracker_;
  std::string last_warning_;
};

// What a log says about its site.
struct SiteFromLog {
  // The site of the first SITE message that passed every check.
  LoadedSite site;
  // Its event's receive time, microseconds.
  int64_t event_utime = 0;
  // SITE messages that passed, and those refused (wire check, hash, site
  // validation) by reason: wire_refusal::* or "hash_mismatch",
  // "invalid_site"; the first refusal in words.
  int64_t accepted = 0;
  int64_t refused = 0;
  std::map<std::string, int64_t> refused_by_reason;
  std::string first_refusal;
  // "" or the disagreement line (SiteHashTracker) over the whole log.
  std::string disagreement;
  // Every content hash the log's valid SITE messages carry (the first
  // kMaxSiteHashes), each with its publishers ("trilat_proc@lab-pc"). More
  // than one: the log holds several sites, and a tool must be told which
  // (ResolveToolSite refuses to pick one without --config).
  std::map<std::string, std::set<std::string>> publishers_by_hash;
  // How many different sites (content hashes) the valid SITE messages
  // carry: the true count, where publishers_by_hash lists the first
  // kMaxSiteHashes.
  int64_t distinct_sites = 0;
  // Valid SITE events whose texts equal an already verified message's (same
  // hash, and texts that hash to it), so they were not parsed again (a live
  // process repeats its site every 5 s).
  int64_t repeats_not_reparsed = 0;
  static constexpr size_t kMaxSiteHashes = 16;
};

// Reads every SITE (and STATUS) event of a log. A SITE whose texts equal
// those of one already verified is counted, not parsed again. False with a one-line error
// when the log cannot be read or holds no SITE that passes ("LOG holds no
// SITE message: give --config" or "... N SITE messages refused (reasons):
// first: ...").
bool ReadSiteFromLog(const std::string& log_path, SiteFromLog* out, std::string* error);

// The one line tools print on stderr: "site: demo_room, hash 1a2b3c4d5e6f,
// roomfix 0.1.0, published by trilat_proc@lab-pc (pid 12)".
std::string DescribeSite(const LoadedSite& loaded);

// The site a tool uses for one log, as every tool says it on stderr
// (docs/analysis.md, "Which site"; tools/tool_site.h prints it): --config
// when given, otherwise the log's SITE.
struct ToolSite {
  bool known = false;
  LoadedSite site;
  // "log" or "--config".
  std::string source;
  // Which site is used: "site from LOG: ..." or "site from --config PATH: ...".
  std::string line;
  // The log's refused SITE messages, disagreeing processes, and the keys at
  // which the log's site differs from --config.
  std::vector<std::string> warnings;
  // Why no site could be had (no SITE and no --config, or a bad --config).
  std::string error;
  // True when --config itself failed to load (always fatal).
  bool config_failed = false;
};

// What a tool uses: the site of --config when given (a warning when the
// log's differs, naming the keys), otherwise the log's. A log with neither
// SITE nor --config is an error saying so, and so is a log whose valid SITE
// messages carry different hashes when --config is not given: the error
// lists each hash with its publishers and asks for --config, rather than
// silently taking the first. `log_path` may be empty (no log).
ToolSite ResolveToolSite(const std::string& config_path, const std::string& log_path);

// When a process publishes its site (issue #28: the whole SITE from every
// process every 5 s was the loudest stream on the bus, 18 % of a demo log).
// A SITE is sent when it matters:
//  - at the process's first heartbeat, and after its site changes (Reset);
//  - by the one process elected for its site, every kSitePeriodUs, so that
//    a log started mid-run (lcm-logger cannot ask) holds the site within
//    that long; the elected one is the smallest publisher identity
//    (process, host, pid) of a verified SITE with the same content hash
//    heard within kSiteElectionWindowUs, self included. Each site in use
//    has its own: two processes that disagree both keep their texts in the
//    log;
//  - by the elected one, at most every kSiteAnswerGapUs, when a newcomer
//    appears (a STATUS from a process not heard within kNewcomerAfterUs):
//    a viewer or a process started on another host has the site within a
//    second instead of a period.
// Failure modes, bounded: a forged STATUS flood of invented names makes the
// elected one answer at most once per kSiteAnswerGapUs; a forged SITE can
// silence the elected one's period only by carrying the same verified
// texts, which keeps the log self-describing all the same; if the elected
// one stops, the next one takes over kSiteElectionWindowUs later. Time is
// the caller's (receive times and heartbeats); the class is not
// thread-safe (the process's schedule is guarded by the site mutex).
class SitePublishSchedule {
 public:
  static constexpr int64_t kSiteElectionWindowUs = 2 * kSitePeriodUs + kSitePeriodUs / 2;
  static constexpr int64_t kSiteAnswerGapUs = 1000000;
  // STATUS comes every second: three missed and a process counts as gone,
  // so its return is a newcomer.
  static constexpr int64_t kNewcomerAfterUs = 3000000;
  // Processes followed for newcomers; past it the oldest is forgotten (a
  // flood of names is bounded in memory and in answers by the gap above).
  static constexpr size_t kMaxPeers = 64;

  // `process`, `host`, `pid` and `content_hash` of this process's site_t.
  void Reset(const site_t& own);
  // A SITE heard (after its texts were verified to hash to content_hash).
  void ObserveSite(const site_t& msg, int64_t recv_utime);
  // Whether ObserveSite would change anything: only a SITE of this
  // process's hash from a smaller identity that is not already known to
  // have published within the last kSiteAnswerGapUs is worth hashing.
  bool WorthVerifying(const site_t& msg, int64_t recv_utime) const;
  void ObserveStatus(const process_status_t& msg, int64_t recv_utime);
  // True when the process should publish now (and records that it did).
  bool Due(int64_t now_utime);
  bool elected(int64_t now_utime) const;
  // Why the last Due() was true: "start", "period", "newcomer".
  const char* last_reason() const { return last_reason_; }

 private:
  using Identity = std::tuple<std::string, std::string, int32_t>;
  Identity self_;
  std::string hash_;
  int64_t last_publish_utime_ = -1;
  int64_t smaller_heard_utime_ = INT64_MIN;
  bool newcomer_pending_ = false;
  std::map<Identity, int64_t> peers_;
  const char* last_reason_ = "";
};

// The site this process loaded: StartProcess sets it, and every
// StatusReporter of the process then publishes it on SITE as the
// process's SitePublishSchedule says, and its hash in STATUS. One per
// process because every node builds its own StatusReporter while the
// process has one site.
void SetProcessSite(std::shared_ptr<const site_t> msg);
std::shared_ptr<const site_t> ProcessSite();
// Publishes the process's site when one is set and its schedule says so.
// True when it published.
bool MaybePublishProcessSite(Bus* bus, int64_t now_utime);
// Subscribes the process's schedule to SITE and STATUS on `bus`, so that it
// hears the other publishers of its site and newcomers (StartProcess does
// this). Without it every process publishes as if elected.
void FollowSitePeers(Bus* bus);

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_SITE_MESSAGE_H_
