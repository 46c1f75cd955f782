// Declarations of the libnifalcon API used by client/device/falcon_device.cpp: only so CI compiles
// it (tests/CMakeLists.txt). Not the library; links nothing.
#include <array>
namespace libnifalcon {
struct FalconGrip { unsigned int getDigitalInputs(); };
class FalconDevice { public:
  template <class T> void setFalconFirmware(); template <class T> void setFalconKinematic(); template <class T> void setFalconGrip();
  bool open(unsigned int); void close(); bool isFirmwareLoaded(); bool runIOLoop(unsigned int = 0);
  std::array<double,3> getPosition(); void setForce(std::array<double,3>); FalconGrip* getFalconGrip(); };
}
