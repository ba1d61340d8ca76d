#include "msgio/udpm_bus.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <linux/sock_diag.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <limits>

#include "msgio/process.h"

namespace roomfix {
namespace {

constexpr uint32_t kMagicShort = 0x4c433032;  // "LC02"
constexpr uint32_t kMagicLong = 0x4c433033;   // "LC03"
constexpr int kShortHeaderBytes = 8;
constexpr int kLongHeaderBytes = 20;
constexpr int kMaxDatagramBytes = 65535;
// LCM's limit for a short message: payload and channel in one datagram.
constexpr int kMaxShortMessageBytes = 65499;
constexpr int kMaxChannelBytes = 63;
// LCM's largest payload per LC03 fragment (lcm_udpm.c,
// LCM_FRAGMENT_MAX_PAYLOAD); fragment 0 carries the channel in it too.
constexpr int kFragmentPayloadBytes = 65423;
// Datagrams read per recvmmsg call.
constexpr int kBatch = 64;
// Room for one SO_RXQ_OVFL control message per datagram.
constexpr size_t kControlBytes = CMSG_SPACE(sizeof(uint32_t)) + 16;

uint32_t Be32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3];
}
uint16_t Be16(const uint8_t* p) { return static_cast<uint16_t>((p[0] << 8) | p[1]); }
void PutBe32(uint8_t* p, uint32_t v) {
  p[0] = static_cast<uint8_t>(v >> 24);
  p[1] = static_cast<uint8_t>(v >> 16);
  p[2] = static_cast<uint8_t>(v >> 8);
  p[3] = static_cast<uint8_t>(v);
}
void PutBe16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v >> 8);
  p[1] = static_cast<uint8_t>(v);
}

}  // namespace

bool ParseUdpmUrl(const std::string& url, UdpmAddress* a, std::string* error) {
  const std::string prefix = "udpm://";
  if (url.rfind(prefix, 0) != 0) {
    *error = "not a udpm:// URL: " + url;
    return false;
  }
  std::string rest = url.substr(prefix.size());
  std::string query;
  if (const size_t q = rest.find('?'); q != std::string::npos) {
    query = rest.substr(q + 1);
    rest = rest.substr(0, q);
  }
  if (!rest.empty()) {
    const size_t colon = rest.find(':');
    a->group = rest.substr(0, colon);
    if (colon != std::string::npos) a->port = std::atoi(rest.c_str() + colon + 1);
  }
  in_addr probe{};
  if (inet_pton(AF_INET, a->group.c_str(), &probe) != 1 || a->port <= 0 || a->port > 65535) {
    *error = "bad multicast group or port in " + url;
    return false;
  }
  size_t start = 0;
  while (start < query.size()) {
    const size_t amp = query.find('&', start);
    const std::string kv = query.substr(start, amp == std::string::npos ? amp : amp - start);
    const size_t eq = kv.find('=');
    const std::string key = kv.substr(0, eq);
    const int value = eq == std::string::npos ? 0 : std::atoi(kv.c_str() + eq + 1);
    if (key == "ttl") {
      a->ttl = value;
    } else if (key == "recv_buf_size") {
      a->recv_buf_size = value;
    }  // Other LCM options (transmit_only, ...) do not apply here.
    if (amp == std::string::npos) break;
    start = amp + 1;
  }
  return true;
}

struct UdpmBus::Partial {
  sockaddr_in from{};
  uint32_t seqno = 0;
  uint32_t total = 0;
  uint16_t count = 0;
  std::string channel;
  bool have_channel = false;
  std::vector<uint8_t> data;
  std::vector<bool> seen;
  int fragments_seen = 0;
  int64_t bytes_seen = 0;
  int64_t first_utime = 0;
  int64_t last_utime = 0;
};

std::unique_ptr<UdpmBus> UdpmBus::Create(const std::string& url, std::string* error,
                                         const FragmentLimits& limits) {
  UdpmAddress a;
  if (!ParseUdpmUrl(url, &a, error)) return nullptr;
  std::unique_ptr<UdpmBus> bus(new UdpmBus());
  bus->limits_ = limits;
  auto fail = [&](const char* what) {
    *error = std::string(what) + " for " + url + ": " + std::strerror(errno);
    return nullptr;
  };
  bus->group_.sin_family = AF_INET;
  bus->group_.sin_port = htons(static_cast<uint16_t>(a.port));
  inet_pton(AF_INET, a.group.c_str(), &bus->group_.sin_addr);

  bus->recv_fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (bus->recv_fd_ < 0) return fail("cannot create a socket");
  const int one = 1;
  // Every LCM process on the host binds the same port.
  ::setsockopt(bus->recv_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
  // The kernel then reports its drop counter with every datagram.
  ::setsockopt(bus->recv_fd_, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof(one));
  // Capped so that a URL cannot make a privileged process pin more kernel
  // memory than a stall of a second or so at 100 000 small messages/s needs.
  constexpr int kMaxRecvBufBytes = 64 << 20;
  const int wanted =
      std::min(a.recv_buf_size > 0 ? a.recv_buf_size : kDefaultRecvBufBytes, kMaxRecvBufBytes);
  // SO_RCVBUFFORCE passes net.core.rmem_max for a process with CAP_NET_ADMIN;
  // anyone else gets SO_RCVBUF, capped at rmem_max by the kernel.
  if (::setsockopt(bus->recv_fd_, SOL_SOCKET, SO_RCVBUFFORCE, &wanted, sizeof(wanted)) != 0) {
    ::setsockopt(bus->recv_fd_, SOL_SOCKET, SO_RCVBUF, &wanted, sizeof(wanted));
  }
  socklen_t len = sizeof(bus->recv_buf_bytes_);
  ::getsockopt(bus->recv_fd_, SOL_SOCKET, SO_RCVBUF, &bus->recv_buf_bytes_, &len);
  // The kernel reports twice what it grants to data (the rest is its
  // bookkeeping), so half of it is what was asked for.
  if (bus->recv_buf_bytes_ / 2 < wanted) {
    spdlog::warn(
        "kernel receive buffer is {} bytes, {} asked for: net.core.rmem_max caps it "
        "(docs/operations.md, \"Losses\")",
        bus->recv_buf_bytes_ / 2, wanted);
  }
  sockaddr_in bind_addr{};
  bind_addr.sin_family = AF_INET;
  bind_addr.sin_port = bus->group_.sin_port;
  bind_addr.sin_addr.s_addr = htonl(INADDR_ANY);
  if (::bind(bus->recv_fd_, reinterpret_cast<sockaddr*>(&bind_addr), sizeof(bind_addr)) != 0) {
    return fail("cannot bind the multicast port");
  }
  ip_mreq mreq{};
  mreq.imr_multiaddr = bus->group_.sin_addr;
  mreq.imr_interface.s_addr = htonl(INADDR_ANY);
  if (::setsockopt(bus->recv_fd_, IPPROTO_IP, IP_ADD_MEMBERSHIP, &mreq, sizeof(mreq)) != 0) {
    return fail("cannot join the multicast group (no multicast route? see docs/operations.md)");
  }

  bus->send_fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (bus->send_fd_ < 0) return fail("cannot create a socket");
  const unsigned char ttl = static_cast<unsigned char>(a.ttl);
  const unsigned char loop = 1;
  ::setsockopt(bus->send_fd_, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof(ttl));
  ::setsockopt(bus->send_fd_, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof(loop));

  bus->buffers_.assign(kBatch, std::vector<uint8_t>(kMaxDatagramBytes));
  bus->controls_.assign(kBatch, std::vector<uint8_t>(kControlBytes));
  return bus;
}

UdpmBus::~UdpmBus() {
  if (recv_fd_ >= 0) ::close(recv_fd_);
  if (send_fd_ >= 0) ::close(send_fd_);
}

bool UdpmBus::PublishRaw(const std::string& channel, const void* data, int size) {
  const int channel_bytes = static_cast<int>(channel.size()) + 1;
  if (channel.size() > kMaxChannelBytes || size < 0) {
    CountPublished(false, channel);
    return false;
  }
  if (size + channel_bytes > kMaxShortMessageBytes) {
    const bool ok = SendFragments(channel, static_cast<const uint8_t*>(data), size);
    CountPublished(ok, channel);
    return ok;
  }
  uint8_t header[kShortHeaderBytes];
  PutBe32(header, kMagicShort);
  PutBe32(header + 4, send_seqno_++);
  iovec iov[3] = {{header, sizeof(header)},
                  {const_cast<char*>(channel.c_str()), static_cast<size_t>(channel_bytes)},
                  {const_cast<void*>(data), static_cast<size_t>(size)}};
  msghdr msg{};
  msg.msg_name = &group_;
  msg.msg_namelen = sizeof(group_);
  msg.msg_iov = iov;
  msg.msg_iovlen = 3;
  const bool ok = ::sendmsg(send_fd_, &msg, 0) == kShortHeaderBytes + channel_bytes + size;
  CountPublished(ok, channel);
  return ok;
}

// As liblcm's lcm_udpm_publish: fragment 0 holds the channel and the first
// bytes, the others kFragmentPayloadBytes each.
bool UdpmBus::SendFragments(const std::string& channel, const uint8_t* data, int size) {
  const int channel_bytes = static_cast<int>(channel.size()) + 1;
  const int64_t count =
      (int64_t{size} + channel_bytes + kFragmentPayloadBytes - 1) / kFragmentPayloadBytes;
  if (count > std::numeric_limits<uint16_t>::max()) return false;
  const uint32_t seqno = send_seqno_++;
  int offset = 0;
  for (int number = 0; number < count; ++number) {
    uint8_t header[kLongHeaderBytes];
    PutBe32(header, kMagicLong);
    PutBe32(header + 4, seqno);
    PutBe32(header + 8, static_cast<uint32_t>(size));
    PutBe32(header + 12, static_cast<uint32_t>(offset));
    PutBe16(header + 16, static_cast<uint16_t>(number));
    PutBe16(header + 18, static_cast<uint16_t>(count));
    const int room = kFragmentPayloadBytes - (number == 0 ? channel_bytes : 0);
    const int chunk = std::min(room, size - offset);
    iovec iov[3];
    int n_iov = 0;
    iov[n_iov++] = {header, sizeof(header)};
    if (number == 0) {
      iov[n_iov++] = {const_cast<char*>(channel.c_str()), static_cast<size_t>(channel_bytes)};
    }
    iov[n_iov++] = {const_cast<uint8_t*>(data + offset), static_cast<size_t>(chunk)};
    msghdr msg{};
    msg.msg_name = &group_;
    msg.msg_namelen = sizeof(group_);
    msg.msg_iov = iov;
    msg.msg_iovlen = static_cast<size_t>(n_iov);
    const ssize_t want = kLongHeaderBytes + (number == 0 ? channel_bytes : 0) + chunk;
    if (::sendmsg(send_fd_, &msg, 0) != want) return false;
    offset += chunk;
  }
  return offset == size;
}

SubscriptionId UdpmBus::SubscribeRaw(const std::string& channel_regex, RawHandler handler) {
  return AddSubscription(channel_regex, std::move(handler));
}

void UdpmBus::Unsubscribe(SubscriptionId id) { RemoveSubscription(id); }

void UdpmBus::Dispatch(const std::string& channel, const uint8_t* data, int size, int64_t utime) {
  DeliverToSubscribers(MessageInfo{channel, utime}, data, size);
}

void UdpmBus::OnDatagram(const uint8_t* p, int n, const sockaddr_in& from, int64_t utime) {
  ++wire_.datagrams;
  const uint32_t magic = n >= kShortHeaderBytes ? Be32(p) : 0;
  if (magic == kMagicShort) {
    const uint8_t* channel = p + kShortHeaderBytes;
    const void* nul = std::memchr(channel, 0, static_cast<size_t>(n - kShortHeaderBytes));
    if (nul != nullptr && static_cast<const uint8_t*>(nul) - channel <= kMaxChannelBytes) {
      const auto* payload = static_cast<const uint8_t*>(nul) + 1;
      Dispatch(std::string(reinterpret_cast<const char*>(channel)), payload,
               static_cast<int>(p + n - payload), utime);
      return;
    }
  } else if (magic == kMagicLong && n >= kLongHeaderBytes) {
    OnFragment(p, n, from, utime);
    return;
  }
  ++wire_.malformed;
  AddLoss(&BusStats::datagrams_malformed, 1, "datagram on the LCM port that is not LCM");
}

void UdpmBus::OnFragment(const uint8_t* p, int n, const sockaddr_in& from, int64_t utime) {
  const uint32_t seqno = Be32(p + 4);
  const uint32_t total = Be32(p + 8);
  const uint32_t offset = Be32(p + 12);
  const uint16_t number = Be16(p + 16);
  const uint16_t count = Be16(p + 18);
  const uint8_t* body = p + kLongHeaderBytes;
  int64_t body_bytes = n - kLongHeaderBytes;
  auto malformed = [&](const char* why) {
    AddLoss(&BusStats::fragments_malformed, 1, std::string("LC03 fragment refused: ") + why);
  };
  if (count == 0 || number >= count) return malformed("fragment number not below the count");
  // Only fragment 0 carries the channel; in any other the bytes are data.
  std::string channel;
  if (number == 0) {
    const void* nul = std::memchr(body, 0, static_cast<size_t>(body_bytes));
    if (nul == nullptr || static_cast<const uint8_t*>(nul) - body > kMaxChannelBytes) {
      return malformed("fragment 0 without a channel name of at most 63 bytes");
    }
    channel.assign(reinterpret_cast<const char*>(body));
    const auto* data = static_cast<const uint8_t*>(nul) + 1;
    body_bytes -= data - body;
    body = data;
  }
  // In 64 bits: liblcm's 32-bit offset + size wraps (see udpm_bus.h).
  if (int64_t{offset} + body_bytes > int64_t{total}) {
    return malformed("offset + size past the declared total");
  }
  Partial* partial = nullptr;
  for (auto& q : partials_) {
    if (q->seqno == seqno && q->from.sin_addr.s_addr == from.sin_addr.s_addr &&
        q->from.sin_port == from.sin_port) {
      partial = q.get();
      break;
    }
  }
  if (partial != nullptr && (partial->total != total || partial->count != count)) {
    // The fragment is checked against the message it claims to belong to,
    // never copied by its own header into another message's buffer.
    return malformed("total or count disagrees with the message's earlier fragments");
  }
  if (partial == nullptr) {
    if (total > limits_.max_message_bytes) {
      AddLoss(&BusStats::fragments_over_budget, 1,
              "LC03 message of " + std::to_string(total) + " bytes refused: over the " +
                  std::to_string(limits_.max_message_bytes) + "-byte cap");
      return;
    }
    // Each fragment but the last carries at least one byte, so a count above
    // the total (plus one for an empty message) cannot be honest.
    if (int64_t{count} > int64_t{total} + 1) return malformed("more fragments than bytes");
    auto over_budget = [&] {
      return partial_bytes_ + total > limits_.budget_bytes ||
             static_cast<int>(partials_.size()) >= limits_.max_partials;
    };
    if (over_budget()) ExpirePartials(utime);
    if (over_budget()) {
      AddLoss(&BusStats::fragments_over_budget, 1,
              "LC03 message refused: partial messages already hold " +
                  std::to_string(partial_bytes_) + " bytes");
      return;
    }
    auto q = std::make_unique<Partial>();
    q->from = from;
    q->seqno = seqno;
    q->total = total;
    q->count = count;
    q->data.resize(total);
    q->seen.assign(count, false);
    q->first_utime = utime;
    q->last_utime = utime;
    partial_bytes_ += total;
    partial = q.get();
    partials_.push_back(std::move(q));
  }
  if (partial->seen[number]) {
    AddLoss(&BusStats::fragments_duplicate, 1, "duplicate LC03 fragment dropped");
    return;
  }
  partial->seen[number] = true;
  ++partial->fragments_seen;
  partial->bytes_seen += body_bytes;
  partial->last_utime = utime;
  if (number == 0) {
    partial->channel = std::move(channel);
    partial->have_channel = true;
  }
  if (body_bytes > 0) std::memcpy(partial->data.data() + offset, body, size_t(body_bytes));
  if (partial->fragments_seen < partial->count) return;

  // Complete: take it out of the store first, so a handler that publishes
  // (and so may reach OnDatagram again) sees a consistent store.
  const auto it = std::find_if(partials_.begin(), partials_.end(),
                               [partial](const auto& q) { return q.get() == partial; });
  const std::unique_ptr<Partial> done = std::move(*it);
  partials_.erase(it);
  partial_bytes_ -= done->total;
  if (done->bytes_seen != int64_t{done->total}) {
    // Every fragment arrived but they overlap or leave a gap.
    AddLoss(&BusStats::fragments_malformed, done->count,
            "LC03 message refused: its fragments do not cover it exactly");
    return;
  }
  Dispatch(done->channel, done->data.data(), static_cast<int>(done->data.size()),
           done->first_utime);
}

void UdpmBus::ExpirePartials(int64_t now_utime) {
  for (auto it = partials_.begin(); it != partials_.end();) {
    if (now_utime - (*it)->last_utime > limits_.expiry_us) {
      partial_bytes_ -= (*it)->total;
      AddLoss(&BusStats::fragments_expired, (*it)->fragments_seen,
              "LC03 message on '" + (*it)->channel + "' expired with " +
                  std::to_string((*it)->count - (*it)->fragments_seen) + " fragments missing");
      it = partials_.erase(it);
    } else {
      ++it;
    }
  }
}

void UdpmBus::RefreshStats() {
  // SO_MEMINFO reads the same counter SO_RXQ_OVFL reports with each
  // datagram, so a STATUS shows an overflow even before the next datagram.
  uint32_t meminfo[SK_MEMINFO_VARS] = {};
  socklen_t len = sizeof(meminfo);
  if (::getsockopt(recv_fd_, SOL_SOCKET, SO_MEMINFO, meminfo, &len) == 0 &&
      len > SK_MEMINFO_DROPS * sizeof(uint32_t)) {
    NoteKernelDrops(meminfo[SK_MEMINFO_DROPS]);
  }
}

void UdpmBus::NoteKernelDrops(uint32_t drops) {
  // Unsigned difference: right across the counter's wrap.
  const uint32_t increase = drops - kernel_drops_seen_;
  if (increase == 0 || increase > (1u << 31)) return;  // Older report.
  kernel_drops_seen_ = drops;
  AddLoss(&BusStats::dropped_kernel_overflow, increase,
          "kernel receive buffer overflowed: " + std::to_string(drops) +
              " datagrams dropped in all (raise recv_buf_size, docs/operations.md)");
}

int UdpmBus::Handle(int timeout_ms) {
  if (timeout_ms > 0) {
    pollfd pfd{recv_fd_, POLLIN, 0};
    const int ready = ::poll(&pfd, 1, timeout_ms);
    if (ready <= 0) {
      if (!partials_.empty()) ExpirePartials(NowUtime());
      return ready < 0 && errno != EINTR ? -1 : 0;
    }
  }
  mmsghdr msgs[kBatch];
  iovec iovs[kBatch];
  sockaddr_in from[kBatch];
  for (int i = 0; i < kBatch; ++i) {
    iovs[i] = {buffers_[i].data(), buffers_[i].size()};
    msgs[i] = {};
    msgs[i].msg_hdr.msg_iov = &iovs[i];
    msgs[i].msg_hdr.msg_iovlen = 1;
    msgs[i].msg_hdr.msg_name = &from[i];
    msgs[i].msg_hdr.msg_namelen = sizeof(from[i]);
    msgs[i].msg_hdr.msg_control = controls_[i].data();
    msgs[i].msg_hdr.msg_controllen = controls_[i].size();
  }
  const int n = ::recvmmsg(recv_fd_, msgs, kBatch, MSG_DONTWAIT, nullptr);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) {
      if (!partials_.empty()) ExpirePartials(NowUtime());
      return 0;
    }
    RecordError(std::string("recvmmsg failed: ") + std::strerror(errno));
    return -1;
  }
  // One clock read per batch: the datagrams of a batch arrived within the
  // time it took to drain them.
  const int64_t utime = NowUtime();
  for (int i = 0; i < n; ++i) {
    // SO_RXQ_OVFL is the only control message this socket asked for, and
    // the kernel sends it only once the socket has dropped something.
    const msghdr& h = msgs[i].msg_hdr;
    if (h.msg_controllen >= CMSG_LEN(sizeof(uint32_t))) {
      const auto* c = reinterpret_cast<const cmsghdr*>(h.msg_control);
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
        uint32_t drops = 0;
        std::memcpy(&drops, CMSG_DATA(c), sizeof(drops));
        NoteKernelDrops(drops);
      }
    }
    OnDatagram(buffers_[i].data(), static_cast<int>(msgs[i].msg_len), from[i], utime);
  }
  // After the batch, not before: the rest of a message may be in it (a
  // process that was stopped finds its partials old but their fragments
  // still waiting in the socket).
  if (!partials_.empty()) ExpirePartials(utime);
  return n;
}

}  // namespace roomfix
