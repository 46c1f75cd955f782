// vsurg-bench msm-step: the implicit mass-spring step on the benchmark scenes (bench/msm_scenes.h),
// standalone so a script can alternate it with a peer's (bench/peers/msm.sh), and --export to
// write the scenes out as the files the peers' harnesses read (bench/peers/pbd).
#pragma once

#include <string>
#include <vector>

namespace vsurg::bench {

int MsmStep(const std::vector<std::string>& args);

}  // namespace vsurg::bench
