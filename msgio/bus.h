#ifndef ROOMFIX_MSGIO_BUS_H_
#define ROOMFIX_MSGIO_BUS_H_

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "msgio/wire_check.h"

namespace lcm {
class LCM;
}

namespace roomfix {

// How a message reached a handler.
struct MessageInfo {
  std::string channel;
  // Host clock when the message was received, microseconds since the Unix
  // epoch; during a replay, the event's timestamp from the log. Nodes take
  // this as "now", which makes a replay deterministic.
  int64_t recv_utime = 0;
};

using RawHandler = std::function<void(const MessageInfo& info, const void* data, int size)>;
using SubscriptionId = int;

// What a bus has seen go wrong, for the process's STATUS.
struct BusStats {
  int64_t published = 0;
  int64_t publish_failures = 0;
  int64_t received = 0;
  // Messages on a subscribed channel refused before decoding (DecodeChecked:
  // wrong type, truncated, a length or count negative or over its cap...):
  // the total, and by `<CHANNEL>.<reason>` (wire_refusal::*). Anyone can
  // invent channel names, so the map holds at most kMaxRefusedChannels
  // channels; refusals on further ones count under `<other>.<reason>`.
  int64_t decode_failures = 0;
  std::map<std::string, int64_t> refused;
  // Handlers that threw; the exception is caught at the bus so it never
  // unwinds into LCM's C code.
  int64_t handler_exceptions = 0;
  std::string last_error;

  // Transport losses (docs/operations.md, "Losses"): each is added into
  // STATUS `dropped` and reported as a counter of the same name.
  // Datagrams the kernel dropped because the socket's receive buffer was full
  // (SO_RXQ_OVFL, or the drops column of /proc/net/udp for liblcm's socket).
  int64_t dropped_kernel_overflow = 0;
  // Messages refused because a subscription queue was full.
  int64_t dropped_queue_overflow = 0;
  // LC03 fragments discarded: their message was not complete in time
  // (expired), did not fit the reassembly budget (over_budget), disagreed
  // with the message they claim to belong to (malformed), or repeated one
  // already held (duplicate).
  int64_t fragments_expired = 0;
  int64_t fragments_over_budget = 0;
  int64_t fragments_malformed = 0;
  int64_t fragments_duplicate = 0;
  // Datagrams on the bus's port that are not LCM at all; refused, not lost.
  int64_t datagrams_malformed = 0;
};

// The message transport a node talks to (after Drake's DrakeLcmInterface):
// raw publish and subscribe by channel regular expression, with typed helpers
// on top that encode and decode LCM types. Channel patterns follow LCM: a
// POSIX extended regular expression that must match the whole channel name.
//
// Implementations (OpenBus in msgio/process.h picks one for a URL):
// UdpmBus (msgio/udpm_bus.h, our own receiver) for udpm://, LcmBus (liblcm)
// for memq:// and where liblcm's udpm:// is asked for by name, LogFileBus
// (msgio/log.h) for file://, and LoopbackBus (synchronous, in process) for
// ReplayLog (the viewer's --log, the benches) and the node tests. `roomfix
// replay` has its own (ReplayBus, tools/replay.cc).
class Bus {
 public:
  virtual ~Bus() = default;

  virtual bool PublishRaw(const std::string& channel, const void* data, int size) = 0;
  virtual SubscriptionId SubscribeRaw(const std::string& channel_regex, RawHandler handler) = 0;
  virtual void Unsubscribe(SubscriptionId id) = 0;

  // Encodes and publishes an LCM type. Returns false (counted) when encoding
  // or sending fails.
  template <class Msg>
  bool Publish(const std::string& channel, const Msg& msg);

  // Subscribes a typed handler. A message that DecodeChecked refuses is
  // counted in decode_failures and refused, and dropped; the handler only
  // ever sees whole, checked messages.
  template <class Msg>
  SubscriptionId Subscribe(const std::string& channel_regex,
                           std::function<void(const Msg& msg, const MessageInfo& info)> handler);

  BusStats stats() const;

  // Waits up to timeout_ms for messages and dispatches those that arrived.
  // Returns the number handled (0 on time-out), or -1 when the transport
  // failed. Buses without a transport of their own handle nothing.
  virtual int Handle(int /*timeout_ms*/) { return 0; }
  // A descriptor that becomes readable when a message is waiting, or -1.
  virtual int Fileno() const { return -1; }
  // Reads counters the transport keeps outside the bus (the kernel's drop
  // count) into stats(); called before each STATUS.
  virtual void RefreshStats() {}

 protected:
  // Calls the handler, catching and counting anything it throws.
  void Deliver(const RawHandler& handler, const MessageInfo& info, const void* data, int size);
  void CountPublished(bool ok, const std::string& channel);
  void CountRefusal(const std::string& channel, const std::string& reason,
                    const std::string& detail);
  void RecordError(const std::string& error);
  // Adds n to a loss counter of BusStats (or sets it, for counters the
  // transport keeps itself), with a reason for last_error.
  void AddLoss(int64_t BusStats::*counter, int64_t n, const std::string& error);
  void SetLoss(int64_t BusStats::*counter, int64_t value);

  // The subscriptions of a bus that matches channels itself (LoopbackBus,
  // LogFileBus, UdpmBus; LcmBus leaves that to liblcm). Delivery iterates
  // over a snapshot, so a handler may publish, subscribe or unsubscribe
  // (an unsubscribed handler is not called again, even within the snapshot).
  SubscriptionId AddSubscription(const std::string& channel_regex, RawHandler handler);
  void RemoveSubscription(SubscriptionId id);
  void DeliverToSubscribers(const MessageInfo& info, const void* data, int size);

 private:
  struct LocalSubscription;
  std::vector<std::shared_ptr<LocalSubscription>> local_subscriptions_;
  SubscriptionId next_local_id_ = 1;
  mutable std::mutex stats_mutex_;
  BusStats stats_;
  std::vector<std::string> refused_channels_;  // at most kMaxRefusedChannels
};

// Distinct channels BusStats::refused names before folding into `<other>`.
inline constexpr int kMaxRefusedChannels = 64;

// A bus over lcm::LCM. Received messages are dispatched from Handle() on the
// calling thread. Processes use it for memq://; udpm:// goes through UdpmBus
// (msgio/udpm_bus.h says why), except where liblcm is asked for by name
// (roomfix_logger --via-liblcm, for `roomfix_bench logger`), and file://
// through LogFileBus (msgio/log.h says why).
//
// Tuned for load: every subscription may queue kLcmQueueCapacity messages
// (liblcm's default is 30, which a 100 000/s burst overflows in 0.3 ms), and
// a udpm:// URL without recv_buf_size gets kDefaultRecvBufBytes. What it
// costs: liblcm keeps each queued datagram in its receive ring at its own size
// plus about 100 bytes, so the queue of one subscription holds at most
// kLcmQueueCapacity x (largest message + 100 B): 1.3 MiB of 32-byte messages,
// 640 MiB in the worst case of 64 KiB ones. liblcm 1.3.1 neither counts nor
// reports what a full queue drops (lcm_try_enqueue_message returns false and
// the datagram is reused), so dropped_queue_overflow stays 0 here; the
// kernel's drops on liblcm's socket are read from /proc/net/udp.
inline constexpr int kLcmQueueCapacity = 10000;
class LcmBus final : public Bus {
 public:
  // Returns nullptr with a one-line reason in *error when LCM cannot start
  // (bad URL, no multicast route, unreadable log file).
  static std::unique_ptr<LcmBus> Create(const std::string& url, std::string* error);
  ~LcmBus() override;

  bool PublishRaw(const std::string& channel, const void* data, int size) override;
  SubscriptionId SubscribeRaw(const std::string& channel_regex, RawHandler handler) override;
  void Unsubscribe(SubscriptionId id) override;

  int Handle(int timeout_ms) override;
  int Fileno() const override;
  void RefreshStats() override;
  const std::string& url() const { return url_; }

 private:
  LcmBus(std::unique_ptr<lcm::LCM> lcm, std::string url);
  struct Subscription;
  std::unique_ptr<lcm::LCM> lcm_;
  std::string url_;
  int udpm_port_ = 0;  // 0: not udpm://.
  std::vector<std::unique_ptr<Subscription>> subscriptions_;
  SubscriptionId next_id_ = 1;
};

// A synchronous in-process bus: Publish delivers at once to every matching
// subscriber, stamped with the bus's clock. The log replayer drives nodes
// through it, so replay runs the same node code as live, with no network and
// no threads.
class LoopbackBus final : public Bus {
 public:
  bool PublishRaw(const std::string& channel, const void* data, int size) override;
  SubscriptionId SubscribeRaw(const std::string& channel_regex, RawHandler handler) override;
  void Unsubscribe(SubscriptionId id) override;

  // Delivers a message as if it arrived at recv_utime (also sets the clock).
  void Inject(const std::string& channel, const void* data, int size, int64_t recv_utime);
  void set_now_utime(int64_t utime) { now_utime_ = utime; }
  int64_t now_utime() const { return now_utime_; }

 private:
  int64_t now_utime_ = 0;
};

// LCM's channel rule: a POSIX extended regular expression that must match the
// whole channel name. Compiled once; an invalid expression matches nothing.
class ChannelPattern {
 public:
  explicit ChannelPattern(const std::string& channel_regex);
  ~ChannelPattern();
  ChannelPattern(const ChannelPattern&) = delete;
  ChannelPattern& operator=(const ChannelPattern&) = delete;
  bool valid() const { return valid_; }
  bool Matches(const std::string& channel) const;

 private:
  struct Compiled;
  std::unique_ptr<Compiled> compiled_;
  bool valid_ = false;
};

bool ChannelMatches(const std::string& channel_regex, const std::string& channel);

// Dispatches the bus's messages until done() holds or timeout_s passes
// (checked every 20 ms at least); returns whether done() held. For tests and
// tools that wait for something to arrive.
bool HandleUntil(Bus* bus, const std::function<bool()>& done, double timeout_s);

template <class Msg>
bool Bus::Publish(const std::string& channel, const Msg& msg) {
  const int size = msg.getEncodedSize();
  std::vector<uint8_t> buffer(static_cast<size_t>(size));
  if (msg.encode(buffer.data(), 0, size) != size) {
    CountPublished(false, channel);
    return false;
  }
  return PublishRaw(channel, buffer.data(), size);
}

template <class Msg>
SubscriptionId Bus::Subscribe(const std::string& channel_regex,
                              std::function<void(const Msg&, const MessageInfo&)> handler) {
  return SubscribeRaw(channel_regex, [this, handler = std::move(handler)](
                                         const MessageInfo& info, const void* data, int size) {
    Msg msg{};
    std::string reason;
    std::string detail;
    if (!DecodeChecked(data, size, &msg, &reason, &detail)) {
      CountRefusal(info.channel, reason, detail);
      return;
    }
    handler(msg, info);
  });
}

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_BUS_H_
