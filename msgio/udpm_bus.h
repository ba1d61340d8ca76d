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
  // Kernel receive buffer to ask for, bytes; 0: kDefaultRecvBufBytes.
  int recv_buf_size = 0;
};
bool ParseUdpmUrl(const std::string& url, UdpmAddress* address, std::string* error);

// What a udpm:// receiver asks the kernel for when the URL names no
// recv_buf_size: 4 MiB holds about 0.05 s of 100 000 small messages/s (the
// kernel charges about 800 bytes per small datagram) or 60 full 64 KiB
// datagrams. The kernel caps it at net.core.rmem_max unless the process may
// use SO_RCVBUFFORCE; the effective size is logged and kept in
// UdpmBus::recv_buf_bytes().
inline constexpr int kDefaultRecvBufBytes = 4 << 20;

// Limits on reassembling fragmented (LC03) messages. roomfix's largest
// message is a camera preview JPEG well under 1 MiB, so a declared size above
// the per-message cap is refused; the budget bounds the memory all partial
// messages hold at once, whatever a sender declares; a partial message whose
// last fragment is older than the expiry is discarded (liblcm sends the
// fragments of a message back to back).
struct FragmentLimits {
  int64_t max_message_bytes = 8 << 20;
  int64_t budget_bytes = 32 << 20;
  int max_partials = 64;
  int64_t expiry_us = 1000000;
};

// Speaks LCM's UDP multicast wire format directly on one socket; every roomfix
// process receives udpm:// through it (msgio/process.cc).
//
// Why not liblcm: (1) liblcm 1.3.1 checks a fragment's offset + size in 32-bit
// arithmetic that wraps, so one 535-byte LC03 datagram with offset 0xFFFFFF00
// on a subscribed channel makes it memcpy 4 GiB past its buffer: lcm-logger
// and every liblcm subscriber die with SIGSEGV (reproduced in a network
// namespace, docs/operations.md "Transport"). liblcm cannot be patched here.
// (2) liblcm drops silently when a subscription's queue is full (no counter,
// no message), so its losses cannot be reported. Throughput is no longer the
// reason: tuned liblcm also keeps up with 100 000 small messages/s
// (`roomfix_bench logger` measures both in one run).
//
// Here Handle() drains the socket with recvmmsg in batches on the caller's
// thread: no queue between the socket and the handlers, so the only place a
// message can be lost to load is the kernel's receive buffer, whose overflow
// the kernel reports with each datagram (SO_RXQ_OVFL) and which is counted in
// BusStats::dropped_kernel_overflow.
//
// Wire format (lcm_udpm, big-endian): a short message is "LC02", a sequence
// number, the channel NUL-terminated and the payload, in one datagram. A long
// message is split into fragments, each "LC03", sequence number, total
// payload size, this fragment's offset in the payload, fragment number and
// count; fragment 0 carries the channel before its data. Each fragment is
// checked against the message it belongs to (same total and count, offset and
// size within the total, number not seen before); refusals are counted in
// BusStats (fragments_malformed, _duplicate, _over_budget, _expired).
class UdpmBus final : public Bus {
 public:
  static std::unique_ptr<UdpmBus> Create(const std::string& url, std::string* error,
                                         const FragmentLimits& limits = FragmentLimits());
  ~UdpmBus() override;

  // Messages up to 65 499 bytes with the channel go in one datagram, longer
  // ones in LC03 fragments as liblcm sends them.
  bool PublishRaw(const std::string& channel, const void* data, int size) override;
  SubscriptionId SubscribeRaw(const std::string& channel_regex, RawHandler handler) override;
  void Unsubscribe(SubscriptionId id) override;
  int Handle(int timeout_ms) override;
  int Fileno() const override { return recv_fd_; }
  void RefreshStats() override;

  struct WireStats {
    int64_t datagrams = 0;
    // Datagrams that are not LCM at all (short, wrong magic, bad channel).
    int64_t malformed = 0;
  };
  WireStats wire_stats() const { return wire_; }
  // The kernel receive buffer as the kernel reports it (SO_RCVBUF: twice the
  // usable size, the other half being its bookkeeping).
  int recv_buf_bytes() const { return recv_buf_bytes_; }
  // Bytes all partial messages hold now (declared totals).
  int64_t partial_bytes() const { return partial_bytes_; }

 private:
  UdpmBus() = default;
  void Dispatch(const std::string& channel, const uint8_t* data, int size, int64_t utime);
  void OnDatagram(const uint8_t* p, int n, const sockaddr_in& from, int64_t utime);
  void OnFragment(const uint8_t* p, int n, const sockaddr_in& from, int64_t utime);
  void ExpirePartials(int64_t now_utime);
  void NoteKernelDrops(uint32_t drops);
  bool SendFragments(const std::string& channel, const uint8_t* data, int size);

  struct Partial;
  FragmentLimits limits_;
  int recv_fd_ = -1;
  int send_fd_ = -1;
  int recv_buf_bytes_ = 0;
  sockaddr_in group_{};
  uint32_t send_seqno_ = 0;
  std::vector<std::unique_ptr<Partial>> partials_;
  int64_t partial_bytes_ = 0;
  std::vector<std::vector<uint8_t>> buffers_;
  std::vector<std::vector<uint8_t>> controls_;
  // The kernel's drop counter for the socket as last reported, to add only
  // its increase (it is a 32-bit counter that may wrap).
  uint32_t kernel_drops_seen_ = 0;
  WireStats wire_;
};

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_UDPM_BUS_H_
