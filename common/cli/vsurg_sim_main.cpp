#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "common/cli/vsurg_sim.h"

int main(int argc, char** argv) {
  try {
    return vsurg::cli::RunVsurgSim(std::vector<std::string>(argv + 1, argv + argc), std::cout,
                                   std::cerr);
  } catch (const std::exception& e) {
    std::cerr << "vsurg-sim: internal error: " << e.what() << "\n";
    return 1;
  }
}
