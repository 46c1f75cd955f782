// vsurg-sim's commands, one family per file (common/cli/): coil_commands.cpp (coil,
// coil-inverse, deform, calibrate), msm_command.cpp (msm), session_commands.cpp (run, trainee),
// score_command.cpp (score), cut_command.cpp (cut). vsurg_sim.cpp dispatches. Private to
// common/cli/.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

namespace vsurg::cli::commands {

using Args = std::vector<std::string>;

int Coil(const Args& args, std::ostream& out, std::ostream& err);
int CoilInverse(const Args& args, std::ostream& out, std::ostream& err);
int Deform(const Args& args, std::ostream& out, std::ostream& err);
int Calibrate(const Args& args, std::ostream& out, std::ostream& err);
int Msm(const Args& args, std::ostream& out, std::ostream& err);
int Run(const Args& args, std::ostream& out, std::ostream& err);
int Trainee(const Args& args, std::ostream& out, std::ostream& err);
int ContactLaw(const Args& args, std::ostream& out, std::ostream& err);
int Search(const Args& args, std::ostream& out, std::ostream& err);
int Score(const Args& args, std::ostream& out, std::ostream& err);
int Cut(const Args& args, std::ostream& out, std::ostream& err);

}  // namespace vsurg::cli::commands
