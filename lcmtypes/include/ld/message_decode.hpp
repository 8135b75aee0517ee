// Decoding messages that arrive from the bus, where any bytes may arrive.
//
// The decoders lcm-gen writes (LCM 1.3.1) trust the counts in the message:
// an array count of 2^31-1 makes them allocate and zero gigabytes before they
// notice the bytes are missing, a string length of 0 or less throws
// std::length_error, and a boolean byte other than 0 or 1 ends up in a C++
// bool (undefined behaviour). decodeMessage first walks the encoding and
// checks every count, length and boolean against the bytes that are really
// there; only a message that passes goes to the generated decoder.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

#include "ld/image_t.hpp"
#include "ld/landmark_list_t.hpp"
#include "ld/qr_code_list_t.hpp"

namespace ld {

/// Decodes exactly one message of the type from `size` bytes at `data`.
/// Returns false, and says why in `error` when given (one line: the type and
/// what was wrong at which byte), when the bytes are not such a message.
bool decodeMessage(const void* data, size_t size, image_t& out, std::string* error = nullptr);
bool decodeMessage(const void* data, size_t size, landmark_list_t& out,
                   std::string* error = nullptr);
bool decodeMessage(const void* data, size_t size, qr_code_list_t& out,
                   std::string* error = nullptr);

/// The LCM fingerprint the bytes start with (the first 8, big-endian); 0
/// when there are fewer.
int64_t fingerprintOf(const void* data, size_t size);

/// When the bytes start with the fingerprint of an earlier version of one of
/// the project's types, which no build since decodes, that version in words
/// ("ld.qr_code_list_t before withheld_track_ids"); else "". A recording
/// made by an older build is said as such, not as a foreign message.
std::string earlierTypeVersion(const void* data, size_t size);

/// A codes message taken as the payloads known by track id, as a consumer
/// that keeps them between messages does (ld-view). Each message lists every
/// payload known for the tracks of its frame, so `payloads` becomes exactly
/// its codes: a payload it leaves out is gone (withheld: its landmark showed
/// another code; forgotten at a jump or a tracker restart; its track
/// dropped), where merging kept it.
void takeCodes(const qr_code_list_t& codes, std::map<int64_t, std::string>& payloads);

}  // namespace ld
