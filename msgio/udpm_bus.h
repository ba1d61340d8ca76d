#ifndef ROOMFIX_MSGIO_UDPM_BUS_H_
#define ROOMFIX_MSGIO_UDPM_BUS_H_

#include <netinet/in.h>
#include <sys/socket.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "msgio/bus.h"

namespace roomfix {

// "udpm://GROUP:PORT?ttl=N&recv_buf_size=B", LCM's multicast URL.
struct UdpmAddress {
  std::string group = "239.255.76.67";
  int port = 7667;
  int ttl = 0;
  int recv_buf_size = 0;
};
bool ParseUdpmUrl(const std::string& url, UdpmAddress* address, std::string* error);

// Speaks LCM's UDP multicast wire format directly on one socket, for the
// processes that must keep up with every message (the logger).
//
// Why: LCM 1.3.1's udpm provider hands each datagram from a reader thread
// through a 200 KB ring buffer and a pipe to lcm_handle(); on a 2-core
// machine it loses messages above about 10 000 per second, whoever the
// subscriber is (roomfix bench logger shows it, lcm-logger included). Here
// Handle() drains the socket with recvmmsg in batches on the caller's thread.
//
// Wire format (lcm_udpm, big-endian): a short message is "LC02", a sequence
// number, the channel NUL-terminated and the payload, in one datagram. A long
// message is split into fragments, each "LC03", sequence number, total
// payload size, this fragment's offset in the payload, fragment number and
// count; fragment 0 carries the channel before its data. This sends short
// messages only (payload plus channel up to 65 499 bytes) and receives both.
class UdpmBus final : public Bus {
 public:
  static std::unique_ptr<UdpmBus> Create(const std::string& url, std::string* error);
  ~UdpmBus() override;

  bool PublishRaw(const std::string& channel, const void* data, int size) override;
  SubscriptionId SubscribeRaw(const std::string& channel_regex, RawHandler handler) override;
  void Unsubscribe(SubscriptionId id) override;
  int Handle(int timeout_ms) override;
  int Fileno() const override { return recv_fd_; }

  struct WireStats {
    int64_t datagrams = 0;
    int64_t malformed = 0;
    int64_t fragments_abandoned = 0;
  };
  WireStats wire_stats() const { return wire_; }

 private:
  UdpmBus() = default;
  void Dispatch(const std::string& channel, const uint8_t* data, int size, int64_t utime);
  void OnDatagram(const uint8_t* p, int n, const sockaddr_in& from, int64_t utime);

  struct Subscription;
  struct Partial;
  int recv_fd_ = -1;
  int send_fd_ = -1;
  sockaddr_in group_{};
  uint32_t send_seqno_ = 0;
  std::vector<std::unique_ptr<Subscription>> subscriptions_;
  std::vector<std::unique_ptr<Partial>> partials_;
  SubscriptionId next_id_ = 1;
  std::vector<std::vector<uint8_t>> buffers_;
  WireStats wire_;
};

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_UDPM_BUS_H_
