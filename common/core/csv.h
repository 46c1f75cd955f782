// RFC 4180 CSV: a strict reader and a field writer that is safe to open in a spreadsheet.
//
// Reader: fields separated by ',', records by CRLF or LF; a field may be quoted with '"', and a
// quoted field may hold commas, line breaks and doubled quotes (""). A quote inside an unquoted
// field, text after a closing quote, or an unterminated quote is an error naming the line.
//
// Writer: quotes a field only when it must (comma, quote, CR, LF, or a leading/trailing space).
// Formula injection (OWASP "CSV injection"): a text field starting with = + - @ TAB or CR would
// be run as a formula by spreadsheet programs, so it gets a leading apostrophe. Numbers are
// written by the caller with CsvNumber and never prefixed, so "-1.5" stays a number.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "common/core/expected.h"

namespace vsurg::csv {

struct Record {
  int line = 0;  // 1-based line where the record starts
  std::vector<std::string> fields;
};

// Blank lines are skipped. `source` names the input in error messages.
Expected<std::vector<Record>> Parse(std::string_view text, const std::string& source);

// Appends one text field (escaped and formula-safe) to `out`.
void AppendText(std::string& out, std::string_view field);
// Appends a number with up to 17 significant digits (round-trip exact), "" when not finite.
void AppendNumber(std::string& out, double value);

}  // namespace vsurg::csv
