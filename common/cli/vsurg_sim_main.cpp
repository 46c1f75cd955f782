#include <exception>
#include <iostream>
#include <new>
#include <string>
#include <vector>

#include "common/cli/vsurg_sim.h"

int main(int argc, char** argv) {
  try {
    return vsurg::cli::RunVsurgSim(std::vector<std::string>(argv + 1, argv + argc), std::cout,
                                   std::cerr);
  } catch (const std::bad_alloc&) {
    // Sizes are checked against a budget first (scene.h); this is the net under that check.
    std::cerr << "vsurg-sim: out of memory: the input is too large for this machine\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "vsurg-sim: internal error: " << e.what() << "\n";
    return 1;
  }
}
