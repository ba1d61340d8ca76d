// Fuzz target: LogReader (msgio/log.h) on arbitrary bytes as an LCM log.
//
// Invariants (abort() on violation):
//  - every byte of the input is either inside a good event or counted as
//    skipped: the reader never loses track of where it is;
//  - good events have the lengths LCM's reader accepts (channel 1 to 999
//    bytes, payload at most kMaxLogEventDataBytes), so nothing larger than
//    the input is ever allocated;
//  - damage regions are in file order, do not overlap and lie in the file;
//  - the good events, written back to back, are a clean log that reads back
//    identically with nothing skipped.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "msgio/log.h"

namespace {

void Check(bool ok) {
  if (!ok) std::abort();
}

void Put(std::vector<uint8_t>* out, uint64_t v, int bytes) {
  for (int i = bytes - 1; i >= 0; --i) out->push_back(static_cast<uint8_t>(v >> (8 * i)));
}

std::vector<uint8_t> Encode(const std::vector<roomfix::LogEvent>& events) {
  std::vector<uint8_t> out;
  for (const roomfix::LogEvent& e : events) {
    Put(&out, 0xEDA1DA01u, 4);
    Put(&out, static_cast<uint64_t>(e.eventnum), 8);
    Put(&out, static_cast<uint64_t>(e.utime), 8);
    Put(&out, e.channel.size(), 4);
    Put(&out, e.data.size(), 4);
    out.insert(out.end(), e.channel.begin(), e.channel.end());
    out.insert(out.end(), e.data.begin(), e.data.end());
  }
  return out;
}

std::vector<roomfix::LogEvent> ReadAll(roomfix::LogReader* reader) {
  std::vector<roomfix::LogEvent> events;
  roomfix::LogEvent e;
  while (reader->Next(&e)) events.push_back(e);
  Check(!reader->Next(&e));  // The end stays the end.
  return events;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto input_bytes = static_cast<int64_t>(size);
  auto reader = roomfix::LogReader::FromBytes(std::vector<uint8_t>(data, data + size), "fuzz");
  const std::vector<roomfix::LogEvent> events = ReadAll(reader.get());

  int64_t event_bytes = 0;
  for (const roomfix::LogEvent& e : events) {
    Check(!e.channel.empty() && e.channel.size() <= roomfix::kMaxLogChannelBytesLcmReads);
    Check(static_cast<int64_t>(e.data.size()) <= roomfix::kMaxLogEventDataBytes);
    event_bytes += roomfix::kLogEventHeaderBytes + static_cast<int64_t>(e.channel.size()) +
                   static_cast<int64_t>(e.data.size());
  }
  Check(event_bytes + reader->bytes_skipped() == input_bytes);
  Check(reader->events_read() == static_cast<int64_t>(events.size()));
  Check(reader->damaged() == (reader->bytes_skipped() > 0));
  Check(reader->damaged() == !reader->DamageSummary().empty());
  Check(reader->damage_regions() >= static_cast<int64_t>(reader->damage().size()));
  int64_t region_end = 0;
  for (const roomfix::LogDamage& d : reader->damage()) {
    Check(d.offset >= region_end && d.bytes > 0 && d.offset + d.bytes <= input_bytes);
    Check(!d.reason.empty());
    region_end = d.offset + d.bytes;
  }

  auto clean = roomfix::LogReader::FromBytes(Encode(events), "fuzz_clean");
  const std::vector<roomfix::LogEvent> again = ReadAll(clean.get());
  Check(!clean->damaged());
  Check(again.size() == events.size());
  for (size_t i = 0; i < events.size(); ++i) {
    Check(again[i].eventnum == events[i].eventnum && again[i].utime == events[i].utime &&
          again[i].channel == events[i].channel && again[i].data == events[i].data);
  }
  return 0;
}
