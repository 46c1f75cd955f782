// Wall-clock time as the store and the exports keep it: integers, microseconds since the Unix
// epoch, UTC; printed and parsed as ISO-8601.
#pragma once

#include <cstdint>
#include <string>

#include "common/core/expected.h"

namespace vsurg {

int64_t NowUs();
std::string IsoTimeUtc(int64_t us);  // 2026-11-21T23:59:01.123456Z
// "2026-11-21" (midnight) or "2026-11-21T10:00:00Z" → µs since the epoch; kInvalidArgument
// naming `field` otherwise.
Expected<int64_t> ParseIsoUtc(const std::string& s, const std::string& field);

}  // namespace vsurg
