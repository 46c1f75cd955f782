// The vsurg tools' strict command lines, over CLI11 (Debian's libcli11-dev, header-only).
//
// Options are `--name value`, `--name=value` or boolean `--name`. CLI11 splits the tokens; every
// value is then checked here (numbers must be finite and consume the whole token, a declared range
// holds), unknown or repeated options and stray positional arguments are errors, and every error
// names the option. A value may start with '-' (negative numbers): an option that takes a value
// takes the next token. Each option is declared once, with its default and bounds, and `Help`
// shows them, so a test can hold a program's --help to the settings it fills.
#pragma once

#include <iosfwd>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/core/expected.h"
#include "common/core/range.h"

namespace vsurg::cli {

using vsurg::Range;

class ArgParser {
 public:
  enum class Kind { kDouble, kInt, kString, kFlag };

  // `command` prefixes help and errors ("vsurg-sim coil"); `summary` is one line of help.
  ArgParser(std::string command, std::string summary);

  // `default_value` empty and `required` false: the option is optional with no default.
  ArgParser& Option(const std::string& name, Kind kind, const std::string& help,
                    bool required = false, const std::string& default_value = "");
  // The last declared option's value must lie within `r` (checked by Parse, shown by Help).
  ArgParser& Within(Range r);

  // Parses args (without the program and command names). `--help` is always accepted.
  Status Parse(const std::vector<std::string>& args);

  bool HelpRequested() const { return help_; }
  std::string Help() const;
  const std::string& command() const { return command_; }

  bool Has(const std::string& name) const;
  double Double(const std::string& name) const;  // after a successful Parse
  int Int(const std::string& name) const;
  std::string String(const std::string& name) const;
  // A comma-separated option's items, empty ones left out ("lan,,metro": lan and metro).
  std::vector<std::string> List(const std::string& name) const;
  bool Flag(const std::string& name) const { return Has(name); }
  // What an option was declared with: its default ("" for none) and its bounds, if any.
  std::string DefaultOf(const std::string& name) const { return specs_.at(name).default_value; }
  std::optional<Range> RangeOf(const std::string& name) const { return specs_.at(name).range; }

 private:
  struct Spec;
  Status LeftOver(const std::vector<std::string>& remaining) const;
  Status Take(const std::string& name, const std::vector<std::string>& results);

  struct Spec {
    Kind kind;
    std::string help;
    bool required;
    std::string default_value;
    std::optional<Range> range;
  };
  std::string command_, summary_;
  std::vector<std::string> order_;
  std::map<std::string, Spec> specs_;
  std::map<std::string, std::string> values_;
  bool help_ = false;
};

// The tools' exit codes: 0 done, 1 failed at run time, 2 bad arguments.
inline constexpr int kExitRuntime = 1, kExitUsage = 2;

// "COMMAND: FIELD: message" on `err`; returns kExitUsage.
int UsageError(std::ostream& err, const std::string& command, const Error& e);

// Parses `args` into `p`. Returns the exit code to stop with (0 after printing --help on `out`,
// kExitUsage after one line on `err` naming the option), or nullopt when the command goes on.
std::optional<int> ParseOrExit(ArgParser& p, const std::vector<std::string>& args,
                               std::ostream& out, std::ostream& err);

}  // namespace vsurg::cli
