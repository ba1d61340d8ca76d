#include "msgio/bus.h"

#include <dirent.h>
#include <regex.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <set>
#include <utility>

#include "msgio/udpm_bus.h"

namespace roomfix {

struct ChannelPattern::Compiled {
  regex_t re;
};

// LCM compiles subscriptions as POSIX extended expressions anchored at both
// ends; doing the same here keeps LoopbackBus and LcmBus in agreement.
ChannelPattern::ChannelPattern(const std::string& channel_regex)
    : compiled_(std::make_unique<Compiled>()) {
  const std::string anchored = "^(" + channel_regex + ")$";
  valid_ = regcomp(&compiled_->re, anchored.c_str(), REG_EXTENDED | REG_NOSUB) == 0;
}

ChannelPattern::~ChannelPattern() {
  if (valid_) regfree(&compiled_->re);
}

bool ChannelPattern::Matches(const std::string& channel) const {
  return valid_ && regexec(&compiled_->re, channel.c_str(), 0, nullptr, 0) == 0;
}

bool ChannelMatches(const std::string& channel_regex, const std::string& channel) {
  return ChannelPattern(channel_regex).Matches(channel);
}

BusStats Bus::stats() const {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  return stats_;
}

void Bus::Deliver(const RawHandler& handler, const MessageInfo& info, const void* data, int size) {
  {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.received;
  }
  try {
    handler(info, data, size);
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.handler_exceptions;
    stats_.last_error = "handler for " + info.channel + " threw: " + e.what();
  } catch (...) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    ++stats_.handler_exceptions;
    stats_.last_error = "handler for " + info.channel + " threw a non-standard exception";
  }
}

void Bus::CountPublished(bool ok, const std::string& channel) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  if (ok) {
    ++stats_.published;
  } else {
    ++stats_.publish_failures;
    stats_.last_error = "publish on " + channel + " failed";
  }
}

void Bus::CountRefusal(const std::string& channel, const std::string& reason,
                       const std::string& detail) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  ++stats_.decode_failures;
  bool named = std::find(refused_channels_.begin(), refused_channels_.end(), channel) !=
               refused_channels_.end();
  if (!named && refused_channels_.size() < static_cast<size_t>(kMaxRefusedChannels)) {
    refused_channels_.push_back(channel);
    named = true;
  }
  ++stats_.refused[(named ? channel : std::string("<other>")) + "." + reason];
  stats_.last_error = "message on " + channel + " refused (" + reason + "): " + detail;
}

void Bus::RecordError(const std::string& error) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.last_error = error;
}

struct Bus::LocalSubscription {
  LocalSubscription(SubscriptionId id_in, const std::string& regex, RawHandler handler_in)
      : id(id_in), pattern(regex), handler(std::move(handler_in)) {}
  SubscriptionId id;
  ChannelPattern pattern;
  RawHandler handler;
  bool active = true;
};

SubscriptionId Bus::AddSubscription(const std::string& channel_regex, RawHandler handler) {
  local_subscriptions_.push_back(
      std::make_shared<LocalSubscription>(next_local_id_++, channel_regex, std::move(handler)));
  return local_subscriptions_.back()->id;
}

void Bus::RemoveSubscription(SubscriptionId id) {
  for (auto it = local_subscriptions_.begin(); it != local_subscriptions_.end(); ++it) {
    if ((*it)->id == id) {
      (*it)->active = false;
      local_subscriptions_.erase(it);
      return;
    }
  }
}

void Bus::DeliverToSubscribers(const MessageInfo& info, const void* data, int size) {
  const auto snapshot = local_subscriptions_;
  for (const auto& s : snapshot) {
    if (s->active && s->pattern.Matches(info.channel)) Deliver(s->handler, info, data, size);
  }
}

void Bus::AddLoss(int64_t BusStats::*counter, int64_t n, const std::string& error) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.*counter += n;
  stats_.last_error = error;
}

void Bus::SetLoss(int64_t BusStats::*counter, int64_t value) {
  std::lock_guard<std::mutex> lock(stats_mutex_);
  stats_.*counter = value;
}

// ---------------------------------------------------------------------------

// Subscriptions go through LCM's C API: the C++ wrapper's method-handler
// subscriptions (lcm-cpp-impl.hpp) cast between unrelated template types,
// which UndefinedBehaviorSanitizer reports on every message.
struct LcmBus::Subscription {
  SubscriptionId id = 0;
  LcmBus* bus = nullptr;
  RawHandler handler;
  lcm_subscription_t* lcm_subscription = nullptr;

  static void OnMessage(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
    auto* self = static_cast<Subscription*>(user);
    const MessageInfo info{channel, rbuf->recv_utime};
    self->bus->Deliver(self->handler, info, rbuf->data, static_cast<int>(rbuf->data_size));
  }
};

std::unique_ptr<LcmBus> LcmBus::Create(const std::string& url_in, std::string* error) {
  std::string url = url_in;
  UdpmAddress address;
  std::string ignored;
  const bool udpm = ParseUdpmUrl(url, &address, &ignored);
  if (udpm && address.recv_buf_size <= 0) {
    url += (url.find('?') == std::string::npos ? "?" : "&") + std::string("recv_buf_size=") +
           std::to_string(kDefaultRecvBufBytes);
  }
  auto lcm = std::make_unique<lcm::LCM>(url);
  if (!lcm->good()) {
    if (error != nullptr) {
      *error = "cannot start LCM on '" + url +
               "' (bad URL, or no multicast route: see docs/operations.md)";
    }
    return nullptr;
  }
  std::unique_ptr<LcmBus> bus(new LcmBus(std::move(lcm), url));
  if (udpm) bus->udpm_port_ = address.port;
  return bus;
}

LcmBus::LcmBus(std::unique_ptr<lcm::LCM> lcm, std::string url)
    : lcm_(std::move(lcm)), url_(std::move(url)) {}

LcmBus::~LcmBus() {
  for (auto& s : subscriptions_) {
    lcm_unsubscribe(lcm_->getUnderlyingLCM(), s->lcm_subscription);
  }
}

bool LcmBus::PublishRaw(const std::string& channel, const void* data, int size) {
  const bool ok = lcm_->publish(channel, data, static_cast<unsigned int>(size)) == 0;
  CountPublished(ok, channel);
  return ok;
}

SubscriptionId LcmBus::SubscribeRaw(const std::string& channel_regex, RawHandler handler) {
  auto s = std::make_unique<Subscription>();
  s->id = next_id_++;
  s->bus = this;
  s->handler = std::move(handler);
  s->lcm_subscription = lcm_subscribe(lcm_->getUnderlyingLCM(), channel_regex.c_str(),
                                      &Subscription::OnMessage, s.get());
  if (s->lcm_subscription != nullptr) {
    lcm_subscription_set_queue_capacity(s->lcm_subscription, kLcmQueueCapacity);
  }
  const SubscriptionId id = s->id;
  subscriptions_.push_back(std::move(s));
  return id;
}

void LcmBus::Unsubscribe(SubscriptionId id) {
  auto it = std::find_if(subscriptions_.begin(), subscriptions_.end(),
                         [id](const auto& s) { return s->id == id; });
  if (it == subscriptions_.end()) return;
  lcm_unsubscribe(lcm_->getUnderlyingLCM(), (*it)->lcm_subscription);
  subscriptions_.erase(it);
}

int LcmBus::Handle(int timeout_ms) {
  const int n = lcm_->handleTimeout(timeout_ms);
  if (n < 0) RecordError("LCM failed while receiving on " + url_);
  return n;
}

int LcmBus::Fileno() const { return lcm_->getFileno(); }

namespace {
// Inodes of this process's sockets, from the /proc/self/fd/N -> socket:[I]
// links.
std::set<uint64_t> OwnSocketInodes() {
  std::set<uint64_t> inodes;
  DIR* dir = ::opendir("/proc/self/fd");
  if (dir == nullptr) return inodes;
  while (const dirent* e = ::readdir(dir)) {
    char link[64] = {0};
    const std::string path = std::string("/proc/self/fd/") + e->d_name;
    if (::readlink(path.c_str(), link, sizeof(link) - 1) <= 0) continue;
    unsigned long long inode = 0;
    if (std::sscanf(link, "socket:[%llu]", &inode) == 1) inodes.insert(inode);
  }
  ::closedir(dir);
  return inodes;
}
}  // namespace

// liblcm's receive socket is its own, so its drop count is read where the
// kernel publishes it for every UDP socket of the network namespace: the
// last column of /proc/net/udp, on the row of a socket this process owns that
// is bound to the bus's port (liblcm's send socket has another port).
void LcmBus::RefreshStats() {
  if (udpm_port_ == 0) return;
  const std::set<uint64_t> own = OwnSocketInodes();
  std::ifstream table("/proc/net/udp");
  std::string line;
  std::getline(table, line);  // Column names.
  int64_t drops_total = 0;
  while (std::getline(table, line)) {
    unsigned local_port = 0;
    unsigned long long inode = 0, drops = 0;
    // sl local_address:port rem_address:port st tx:rx tr:when retrnsmt uid
    // timeout inode ref pointer drops
    if (std::sscanf(line.c_str(),
                    " %*d: %*x:%x %*x:%*x %*x %*x:%*x %*x:%*x %*x %*u %*d %llu %*d %*x %llu",
                    &local_port, &inode, &drops) != 3) {
      continue;
    }
    if (static_cast<int>(local_port) == udpm_port_ && own.count(inode) > 0) {
      drops_total += static_cast<int64_t>(drops);
    }
  }
  SetLoss(&BusStats::dropped_kernel_overflow, drops_total);
}

// ---------------------------------------------------------------------------

bool LoopbackBus::PublishRaw(const std::string& channel, const void* data, int size) {
  CountPublished(true, channel);
  Inject(channel, data, size, now_utime_);
  return true;
}

void LoopbackBus::Inject(const std::string& channel, const void* data, int size,
                         int64_t recv_utime) {
  now_utime_ = recv_utime;
  DeliverToSubscribers(MessageInfo{channel, recv_utime}, data, size);
}

SubscriptionId LoopbackBus::SubscribeRaw(const std::string& channel_regex, RawHandler handler) {
  return AddSubscription(channel_regex, std::move(handler));
}

void LoopbackBus::Unsubscribe(SubscriptionId id) { RemoveSubscription(id); }

bool HandleUntil(Bus* bus, const std::function<bool()>& done, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!done()) {
    if (std::chrono::steady_clock::now() >= end) return false;
    bus->Handle(20);
  }
  return true;
}

}  // namespace roomfix
