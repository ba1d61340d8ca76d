#ifndef ROOMFIX_TESTS_TESTING_RAW_LOG_EVENT_H_
#define ROOMFIX_TESTS_TESTING_RAW_LOG_EVENT_H_

#include <cstdint>
#include <string>

namespace roomfix {
namespace testing {

// One event in LCM's log format (big-endian: sync word 0xEDA1DA01, event
// number, timestamp, channel length, data length, channel, data) with the
// lengths as given rather than as measured: the damage a log reader must
// survive is in the lengths.
inline std::string RawLogEvent(int64_t eventnum, int64_t utime, const std::string& channel,
                               const std::string& data, int32_t channel_bytes, int32_t data_bytes) {
  std::string out;
  auto put = [&out](uint64_t v, int bytes) {
    for (int i = bytes - 1; i >= 0; --i) out.push_back(static_cast<char>(v >> (8 * i)));
  };
  put(0xEDA1DA01u, 4);
  put(static_cast<uint64_t>(eventnum), 8);
  put(static_cast<uint64_t>(utime), 8);
  put(static_cast<uint32_t>(channel_bytes), 4);
  put(static_cast<uint32_t>(data_bytes), 4);
  return out + channel + data;
}

}  // namespace testing
}  // namespace roomfix

#endif  // ROOMFIX_TESTS_TESTING_RAW_LOG_EVENT_H_
