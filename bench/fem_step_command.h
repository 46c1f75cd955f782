// vsurg-bench fem-step: one corotational implicit FEM step timed on the twisted bar of
// BM_FemStep, standalone so a script can alternate it with a peer's (bench/peers/fem.sh), and
// the bar written out as files the peer reads.
#pragma once

#include <string>
#include <vector>

namespace vsurg::bench {

int FemStep(const std::vector<std::string>& args);

}  // namespace vsurg::bench
