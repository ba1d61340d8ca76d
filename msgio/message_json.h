#ifndef ROOMFIX_MSGIO_MESSAGE_JSON_H_
#define ROOMFIX_MSGIO_MESSAGE_JSON_H_

#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>

namespace roomfix {

// The roomfix type whose LCM fingerprint the payload starts with
// ("roomfix.pose2d_t"), or nullptr when it is not one of ours.
const char* RoomfixTypeName(const void* data, int size);

// The fingerprint of every top-level roomfix message type, by name.
int64_t RoomfixTypeFingerprint(const std::string& type_name);

// The refusal reason MessageToJson gives a payload that is no roomfix type.
inline constexpr char kUnknownTypeReason[] = "unknown_type";

// Decodes any top-level roomfix message into one line of JSON with every
// field ({"type": "roomfix.pose2d_t", "utime": ..., ...}), written by
// nlohmann's dump(): a double in the shortest form that reads back to the
// same bits (0.1, 4.0, -0.0), NaN and infinities as null, and bytes of a
// string that are not UTF-8 as U+FFFD, so the line always parses. The
// payload goes through DecodeChecked (wire_check.h) first.
// False for an unknown type or a refused payload, with a line for humans in
// *error and the counting name in *reason (kUnknownTypeReason or one of
// wire_refusal::*); either may be null.
bool MessageToJson(const void* data, int size, std::string* json, std::string* error,
                   std::string* reason = nullptr);

// The same as a value (keys in the message's field order), for a caller
// that wraps it in its own object (`roomfix listen`); dump it as
// MessageToJson does, with error_handler_t::replace (the default handler
// throws on a string that is not UTF-8, and strings are a publisher's bytes).
bool MessageToJsonValue(const void* data, int size, nlohmann::ordered_json* json,
                        std::string* error, std::string* reason = nullptr);

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_MESSAGE_JSON_H_
