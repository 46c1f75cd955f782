#include "common/core/log.h"

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <mutex>

#include "common/core/json_escape.h"
#include "common/core/time.h"

namespace vsurg {
namespace {

std::atomic<LogFormat> g_format{LogFormat::kLogfmt};

// `v` between double quotes, escaped as JSON escapes (which logfmt readers also take).
void Quoted(std::string_view v, std::string& out) {
  out += '"';
  AppendJsonEscaped(out, v);
  out += '"';
}

// logfmt: bare when the value has no space, quote, '=' or control character; quoted otherwise.
void LogfmtValue(std::string_view v, std::string& out) {
  bool bare = !v.empty();
  for (const char ch : v)
    if (ch == ' ' || ch == '"' || ch == '=' || ch == '\\' || static_cast<unsigned char>(ch) < 0x20)
      bare = false;
  if (bare)
    out += v;
  else
    Quoted(v, out);
}

}  // namespace

LogValue::LogValue(double v) {
  if (std::isfinite(v)) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    text = buf;
    number = true;
  } else {
    text = std::isnan(v) ? "nan" : v > 0 ? "inf" : "-inf";
  }
}

void SetLogFormat(LogFormat format) {
  g_format.store(format, std::memory_order_relaxed);
}

bool ParseLogFormat(std::string_view name, LogFormat* out) {
  if (name == "logfmt")
    *out = LogFormat::kLogfmt;
  else if (name == "json")
    *out = LogFormat::kJson;
  else
    return false;
  return true;
}

std::string FormatLogLine(int64_t ts_us, std::string_view component, std::string_view event,
                          const LogFields& fields, LogFormat format) {
  std::string out;
  out.reserve(96 + 24 * fields.size());
  if (format == LogFormat::kJson) {
    out += "{\"ts\":";
    Quoted(IsoTimeUtc(ts_us), out);
    out += ",\"component\":";
    Quoted(component, out);
    out += ",\"event\":";
    Quoted(event, out);
    for (const auto& [key, value] : fields) {
      out += ',';
      Quoted(key, out);
      out += ':';
      if (value.number)
        out += value.text;
      else
        Quoted(value.text, out);
    }
    out += '}';
    return out;
  }
  out += "ts=" + IsoTimeUtc(ts_us) + " component=";
  LogfmtValue(component, out);
  out += " event=";
  LogfmtValue(event, out);
  for (const auto& [key, value] : fields) {
    out += ' ';
    out += key;
    out += '=';
    LogfmtValue(value.text, out);
  }
  return out;
}

void LogEvent(std::string_view component, std::string_view event, const LogFields& fields) {
  std::string line =
      FormatLogLine(NowUs(), component, event, fields, g_format.load(std::memory_order_relaxed));
  line += '\n';
  // One write per line, so that lines from several threads never interleave.
  static std::mutex mutex;
  std::lock_guard lock(mutex);
  std::fwrite(line.data(), 1, line.size(), stderr);
  std::fflush(stderr);
}

}  // namespace vsurg
