// vsurg-bench haptic-rtt and udp-floor: the haptic round trip and its floor on loopback.
#pragma once

#include <string>
#include <vector>

namespace vsurg::bench {

int HapticRtt(const std::vector<std::string>& args);
int UdpFloor(const std::vector<std::string>& args);

}  // namespace vsurg::bench
