#ifndef ROOMFIX_CORE_WORLD_FILE_IO_H_
#define ROOMFIX_CORE_WORLD_FILE_IO_H_

#include <cstddef>
#include <istream>
#include <string>

namespace roomfix {

// The largest configuration file (site, calibration, the CSV files the tools
// read) that ReadConfigFile accepts: 4 MiB. The project's real files are a
// few kB; the cap exists so that /dev/zero, a log or an image named by
// mistake is refused at once instead of being read until memory runs out.
inline constexpr size_t kConfigFileCapBytes = size_t{4} << 20;

// Reads a whole configuration file into *text. Refuses, with a one-line
// *error naming the file, anything that is not a regular file (a folder, a
// FIFO, a device such as /dev/zero: "PATH: not a regular file (a folder)"),
// a file that cannot be opened or read, and a file over `cap_bytes` ("PATH:
// 5000000 bytes, over the 4 MiB cap for configuration files"). The cap is
// enforced while reading too, so a file that grows while it is read cannot
// get past it. Never blocks on a FIFO (it is opened non-blocking and
// refused).
bool ReadConfigFile(const std::string& path, std::string* text, std::string* error,
                    size_t cap_bytes = kConfigFileCapBytes);

// Writes `bytes` to `path` and checks every step: open, each write, fsync
// and close. False with "PATH: cannot write: REASON" (REASON from errno, e.g.
// "No space left on device"). A regular file (or a new one) is written to a
// hidden partial file in the same folder (PartialPathFor, with the pid and a
// count appended) and renamed over `path` only once it is complete, so a
// failed write leaves the old file or none, never a file that stops short
// (issue #28); a link is replaced at the file it names. A device, FIFO or
// terminal (/dev/stdout, /dev/full) is written in place.
bool WriteOutputFile(const std::string& path, const std::string& bytes, std::string* error);

// ".NAME.partial" in the folder of `target`: the prefix of the hidden file a
// writer fills before renaming it to `target` (WriteOutputFile,
// camera::CheckedVideoWriter). A leftover one (a killed writer) is named so.
std::string PartialPathFor(const std::string& target);

// The longest line a streaming text input (roomfix map, solve: CSV or JSON
// lines, possibly standard input) may have: 64 KiB. Their real lines are
// under 200 bytes; /dev/zero or a binary file is one endless "line".
inline constexpr size_t kMaxInputLineBytes = size_t{64} << 10;

enum class LineRead { kLine, kEnd, kTooLong };

// std::getline with a bound: kTooLong as soon as a line exceeds `max_bytes`
// (without reading the rest of it, which may never end), kEnd at the end of
// the stream.
LineRead ReadBoundedLine(std::istream& in, std::string* line,
                         size_t max_bytes = kMaxInputLineBytes);

// "4 MiB", "512 KiB" or "100 bytes", for messages.
std::string ByteSizeText(size_t bytes);

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_FILE_IO_H_
