// The processes' event log on stderr: one line per event, either logfmt (the default, for a
// person at a terminal) or JSON lines (--log-format json: for a log pipeline, Loki, Elasticsearch):
//
//   ts=2026-11-26T17:03:08.314279Z component=vsurg-sessions event=session_started session=12
//   node=sim-2
//   {"ts":"2026-11-26T17:03:08.314279Z","component":"vsurg-sessions","event":"session_started","session":12,"node":"sim-2"}
//
// Every line about a session carries its id as `session` (the dashboard's and the store's id),
// so one session's life can be followed across the control plane, its node and its station.
// Fields are key/value pairs; a value given as a number is a JSON number. Names of
// people never go in a log line (a session id leads to them through the store, for those
// allowed to look).
//
// Thread safety: LogEvent from any thread (each line is written whole); SetLogFormat once, at
// start, before other threads log.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace vsurg {

enum class LogFormat { kLogfmt, kJson };
void SetLogFormat(LogFormat format);
// "logfmt" or "json"; false for anything else.
bool ParseLogFormat(std::string_view name, LogFormat* out);

// A field's value: text, or a number (a JSON number; logfmt writes both bare when it can).
// Numbers are numbers by type, never by look: an id like "0123" or a hex instance stays text.
struct LogValue {
  std::string text;
  bool number = false;
  LogValue(std::string t) : text(std::move(t)) {}  // NOLINT: implicit, as fields are written
  LogValue(const char* t) : text(t) {}             // NOLINT
  LogValue(std::string_view t) : text(t) {}        // NOLINT
  LogValue(int v) : text(std::to_string(v)), number(true) {}                 // NOLINT
  LogValue(long v) : text(std::to_string(v)), number(true) {}                // NOLINT
  LogValue(long long v) : text(std::to_string(v)), number(true) {}           // NOLINT
  LogValue(unsigned v) : text(std::to_string(v)), number(true) {}            // NOLINT
  LogValue(unsigned long v) : text(std::to_string(v)), number(true) {}       // NOLINT
  LogValue(unsigned long long v) : text(std::to_string(v)), number(true) {}  // NOLINT
  LogValue(double v);  // NOLINT: %.6g; a NaN or an infinity is text ("nan", "inf")
};
using LogFields = std::vector<std::pair<std::string, LogValue>>;

// One line: ts (UTC, µs), component, event, then the fields in order.
void LogEvent(std::string_view component, std::string_view event, const LogFields& fields = {});
// The line LogEvent would write at `ts_us`, without its newline (for tests).
std::string FormatLogLine(int64_t ts_us, std::string_view component, std::string_view event,
                          const LogFields& fields, LogFormat format);

}  // namespace vsurg
