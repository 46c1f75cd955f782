#include "common/cli/vsurg_sim.h"

#include <ostream>

#include "common/cli/commands.h"
#include "common/core/args.h"

namespace vsurg::cli {
namespace {

const char* kTopHelp =
    "usage: vsurg-sim <command> [options]\n\n"
    "The headless front of the vsurg simulation core.\n\n"
    "commands:\n"
    "  coil          forward coil-spring torsion model: torque -> cutoff layer, twist\n"
    "  coil-inverse  inverse coil-spring model: twist -> torque and stiffness\n"
    "  deform        twist a built-in limb scene and write the deformed mesh as OBJ\n"
    "  calibrate     fit the coil model to Saint-Venant torsion and report the residuals\n"
    "  msm           press a mass-spring tissue (sphere, limb or OBJ) and report energies and "
    "force\n"
    "  run           replay a stylus trajectory through a scene and print the trial metrics\n"
    "  trainee       write a scripted trainee's trajectory (good, hesitant, rough)\n"
    "  contact-law   press a scene as the good trainee and print its contact's tissue law\n"
    "  search        draw a palpation's case and search it with a scripted examiner\n"
    "  cut           run the pattern-cutting drill with a scripted hand\n"
    "  score         weighted evaluation report (the coil-spring paper eq. 9-11) with rater "
    "reliability\n\n"
    "`vsurg-sim <command> --help` describes each command's options.\n";

}  // namespace

int RunVsurgSim(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  if (args.empty()) {
    err << "vsurg-sim: a command is required (coil, coil-inverse, deform, calibrate, msm, run, "
           "trainee, contact-law, search, score, cut; see --help)\n";
    return kExitUsage;
  }
  const std::string& cmd = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (cmd == "--help" || cmd == "-h" || cmd == "help") {
    out << kTopHelp;
    return 0;
  }
  if (cmd == "coil") return commands::Coil(rest, out, err);
  if (cmd == "coil-inverse") return commands::CoilInverse(rest, out, err);
  if (cmd == "deform") return commands::Deform(rest, out, err);
  if (cmd == "calibrate") return commands::Calibrate(rest, out, err);
  if (cmd == "msm") return commands::Msm(rest, out, err);
  if (cmd == "run") return commands::Run(rest, out, err);
  if (cmd == "trainee") return commands::Trainee(rest, out, err);
  if (cmd == "contact-law") return commands::ContactLaw(rest, out, err);
  if (cmd == "search") return commands::Search(rest, out, err);
  if (cmd == "score") return commands::Score(rest, out, err);
  if (cmd == "cut") return commands::Cut(rest, out, err);
  err << "vsurg-sim: unknown command '" << cmd
      << "' (coil, coil-inverse, deform, calibrate, msm, run, trainee, contact-law, search, score, "
         "cut; "
         "see "
         "--help)\n";
  return kExitUsage;
}

}  // namespace vsurg::cli
