#include "msgio/udpm_bus.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

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
// Datagrams read per recvmmsg call.
constexpr int kBatch = 64;
// Long messages being reassembled at once; the oldest is abandoned beyond.
constexpr size_t kMaxPartials = 16;

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

struct UdpmBus::Subscription {
  Subscription(SubscriptionId id_in, const std::string& regex, RawHandler h)
      : id(id_in), pattern(regex), handler(std::move(h)) {}
  SubscriptionId id;
  ChannelPattern pattern;
  RawHandler handler;
};

struct UdpmBus::Partial {
  sockaddr_in from{};
  uint32_t seqno = 0;
  std::string channel;
  std::vector<uint8_t> data;
  int remaining = 0;
  int64_t first_utime = 0;
};

std::unique_ptr<UdpmBus> UdpmBus::Create(const std::string& url, std::string* error) {
  UdpmAddress a;
  if (!ParseUdpmUrl(url, &a, error)) return nullptr;
  std::unique_ptr<UdpmBus> bus(new UdpmBus());
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
  if (a.recv_buf_size > 0) {
    ::setsockopt(bus->recv_fd_, SOL_SOCKET, SO_RCVBUF, &a.recv_buf_size, sizeof(a.recv_buf_size));
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
  return bus;
}

UdpmBus::~UdpmBus() {
  if (recv_fd_ >= 0) ::close(recv_fd_);
  if (send_fd_ >= 0) ::close(send_fd_);
}

bool UdpmBus::PublishRaw(const std::string& channel, const void* data, int size) {
  const int channel_bytes = static_cast<int>(channel.size()) + 1;
  if (channel.size() > kMaxChannelBytes || size < 0 ||
      size + channel_bytes > kMaxShortMessageBytes) {
    CountPublished(false, channel);
    return false;
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

SubscriptionId UdpmBus::SubscribeRaw(const std::string& channel_regex, RawHandler handler) {
  subscriptions_.push_back(
      std::make_unique<Subscription>(next_id_++, channel_regex, std::move(handler)));
  return subscriptions_.back()->id;
}

void UdpmBus::Unsubscribe(SubscriptionId id) {
  for (auto it = subscriptions_.begin(); it != subscriptions_.end(); ++it) {
    if ((*it)->id == id) {
      subscriptions_.erase(it);
      return;
    }
  }
}

void UdpmBus::Dispatch(const std::string& channel, const uint8_t* data, int size, int64_t utime) {
  const MessageInfo info{channel, utime};
  for (const auto& s : subscriptions_) {
    if (s->pattern.Matches(channel)) Deliver(s->handler, info, data, size);
  }
}

void UdpmBus::OnDatagram(const uint8_t* p, int n, const sockaddr_in& from, int64_t utime) {
  ++wire_.datagrams;
  if (n < kShortHeaderBytes) {
    ++wire_.malformed;
    return;
  }
  const uint32_t magic = Be32(p);
  if (magic == kMagicShort) {
    const uint8_t* channel = p + kShortHeaderBytes;
    const void* nul = std::memchr(channel, 0, static_cast<size_t>(n - kShortHeaderBytes));
    if (nul == nullptr || static_cast<const uint8_t*>(nul) - channel > kMaxChannelBytes) {
      ++wire_.malformed;
      return;
    }
    const auto* payload = static_cast<const uint8_t*>(nul) + 1;
    Dispatch(std::string(reinterpret_cast<const char*>(channel)), payload,
             static_cast<int>(p + n - payload), utime);
    return;
  }
  if (magic != kMagicLong || n < kLongHeaderBytes) {
    ++wire_.malformed;
    return;
  }
  const uint32_t seqno = Be32(p + 4);
  const uint32_t total = Be32(p + 8);
  const uint32_t offset = Be32(p + 12);
  const uint16_t number = Be16(p + 16);
  const uint16_t count = Be16(p + 18);
  const uint8_t* body = p + kLongHeaderBytes;
  int body_bytes = n - kLongHeaderBytes;
  if (count == 0 || number >= count || total > (1u << 26)) {
    ++wire_.malformed;
    return;
  }
  Partial* partial = nullptr;
  for (auto& q : partials_) {
    if (q->seqno == seqno && q->from.sin_addr.s_addr == from.sin_addr.s_addr &&
        q->from.sin_port == from.sin_port) {
      partial = q.get();
    }
  }
  if (partial == nullptr) {
    if (partials_.size() >= kMaxPartials) {
      partials_.erase(partials_.begin());
      ++wire_.fragments_abandoned;
    }
    auto q = std::make_unique<Partial>();
    q->from = from;
    q->seqno = seqno;
    q->data.resize(total);
    q->remaining = count;
    q->first_utime = utime;
    partial = q.get();
    partials_.push_back(std::move(q));
  }
  if (number == 0) {
    const void* nul = std::memchr(body, 0, static_cast<size_t>(body_bytes));
    if (nul == nullptr) {
      ++wire_.malformed;
      return;
    }
    partial->channel.assign(reinterpret_cast<const char*>(body));
    const auto* data = static_cast<const uint8_t*>(nul) + 1;
    body_bytes -= static_cast<int>(data - body);
    body = data;
  }
  if (offset + static_cast<uint32_t>(body_bytes) > total) {
    ++wire_.malformed;
    return;
  }
  std::memcpy(partial->data.data() + offset, body, static_cast<size_t>(body_bytes));
  if (--partial->remaining > 0) return;
  const Partial done = std::move(*partial);
  for (auto it = partials_.begin(); it != partials_.end(); ++it) {
    if (it->get() == partial) {
      partials_.erase(it);
      break;
    }
  }
  Dispatch(done.channel, done.data.data(), static_cast<int>(done.data.size()), done.first_utime);
}

int UdpmBus::Handle(int timeout_ms) {
  if (timeout_ms > 0) {
    pollfd pfd{recv_fd_, POLLIN, 0};
    const int ready = ::poll(&pfd, 1, timeout_ms);
    if (ready <= 0) return ready < 0 && errno != EINTR ? -1 : 0;
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
  }
  const int n = ::recvmmsg(recv_fd_, msgs, kBatch, MSG_DONTWAIT, nullptr);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return 0;
    RecordError(std::string("recvmmsg failed: ") + std::strerror(errno));
    return -1;
  }
  // One clock read per batch: the datagrams of a batch arrived within the
  // time it took to drain them.
  const int64_t utime = NowUtime();
  for (int i = 0; i < n; ++i) {
    OnDatagram(buffers_[i].data(), static_cast<int>(msgs[i].msg_len), from[i], utime);
  }
  return n;
}

}  // namespace roomfix
