#include "common/core/time.h"

#include <chrono>
#include <cstdio>
#include <ctime>

namespace vsurg {

int64_t NowUs() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string IsoTimeUtc(int64_t us) {
  const int64_t secs = us >= 0 ? us / 1000000 : (us - 999999) / 1000000;
  const auto frac = static_cast<int>(us - secs * 1000000);
  const std::time_t t = static_cast<std::time_t>(secs);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%06dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, frac);
  return buf;
}

Expected<int64_t> ParseIsoUtc(const std::string& s, const std::string& field) {
  std::tm tm{};
  int y = 0, mo = 0, d = 0, h = 0, mi = 0, sec = 0;
  char tail = 0;
  const int n =
      std::sscanf(s.c_str(), "%4d-%2d-%2dT%2d:%2d:%2d%c", &y, &mo, &d, &h, &mi, &sec, &tail);
  const bool date_only = n == 3 && s.size() == 10;
  if (!date_only && !(n == 7 && tail == 'Z' && s.size() == 20))
    return InvalidArgument(field, "expected 2026-11-21 or 2026-11-21T10:00:00Z");
  if (mo < 1 || mo > 12 || d < 1 || d > 31 || h > 23 || mi > 59 || sec > 60)
    return InvalidArgument(field, "not a valid date/time");
  tm.tm_year = y - 1900;
  tm.tm_mon = mo - 1;
  tm.tm_mday = d;
  tm.tm_hour = h;
  tm.tm_min = mi;
  tm.tm_sec = sec;
  return static_cast<int64_t>(timegm(&tm)) * 1000000;
}

}  // namespace vsurg
