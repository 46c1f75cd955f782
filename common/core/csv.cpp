#include "common/core/csv.h"

#include <charconv>
#include <cmath>

namespace vsurg::csv {

Expected<std::vector<Record>> Parse(std::string_view text, const std::string& source) {
  std::vector<Record> records;
  Record current;
  std::string field;
  int line = 1;
  size_t i = 0;
  bool record_started = false;
  auto fail = [&](const std::string& what) {
    return Error{ErrorCode::kParseError, source + ":" + std::to_string(line) + ": " + what, source};
  };
  auto end_record = [&] {
    current.fields.push_back(std::move(field));
    field.clear();
    const bool blank = current.fields.size() == 1 && current.fields[0].empty();
    if (!blank) records.push_back(std::move(current));
    current = Record{};
    record_started = false;
  };
  while (i < text.size()) {
    if (!record_started) {
      current.line = line;
      record_started = true;
    }
    const char c = text[i];
    if (c == '"') {
      if (!field.empty()) return fail("quote inside an unquoted field");
      ++i;
      bool closed = false;
      while (i < text.size()) {
        if (text[i] == '"') {
          if (i + 1 < text.size() && text[i + 1] == '"') {
            field.push_back('"');
            i += 2;
            continue;
          }
          ++i;
          closed = true;
          break;
        }
        if (text[i] == '\n') ++line;
        field.push_back(text[i++]);
      }
      if (!closed) return fail("unterminated quoted field");
      if (i < text.size() && text[i] != ',' && text[i] != '\n' && text[i] != '\r')
        return fail("text after a closing quote");
      continue;
    }
    if (c == ',') {
      current.fields.push_back(std::move(field));
      field.clear();
      ++i;
      continue;
    }
    if (c == '\r' || c == '\n') {
      if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
      ++i;
      end_record();
      ++line;
      continue;
    }
    field.push_back(c);
    ++i;
  }
  if (record_started) end_record();
  return records;
}

void AppendText(std::string& out, std::string_view field) {
  const bool formula = !field.empty() && (field[0] == '=' || field[0] == '+' || field[0] == '-' ||
                                          field[0] == '@' || field[0] == '\t' || field[0] == '\r');
  const bool quote = formula || field.find_first_of(",\"\r\n") != std::string_view::npos ||
                     (!field.empty() && (field.front() == ' ' || field.back() == ' '));
  if (!quote) {
    out.append(field);
    return;
  }
  out.push_back('"');
  if (formula) out.push_back('\'');
  for (char c : field) {
    if (c == '"') out.push_back('"');
    out.push_back(c);
  }
  out.push_back('"');
}

void AppendNumber(std::string& out, double value) {
  if (!std::isfinite(value)) return;
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, value);
  out.append(buf, r.ptr);
}

}  // namespace vsurg::csv
