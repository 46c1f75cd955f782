// Declarations of the OpenHaptics HD API as its reference manual documents them: only so CI
// compiles client/device/openhaptics_device.cpp (tests/CMakeLists.txt). Not the SDK; links nothing.
typedef unsigned int HHD; typedef double HDdouble; typedef int HDint; typedef unsigned int HDenum;
typedef unsigned long HDSchedulerHandle; typedef unsigned int HDCallbackCode; typedef unsigned short HDushort;
#define HDCALLBACK
#define HD_DEFAULT_DEVICE nullptr
#define HD_INVALID_HANDLE 0xFFFFFFFF
#define HD_CALLBACK_DONE 0
#define HD_CALLBACK_CONTINUE 1
#define HD_DEFAULT_SCHEDULER_PRIORITY 0
#define HD_CURRENT_POSITION 0x2050
#define HD_CURRENT_TRANSFORM 0x2052
#define HD_CURRENT_BUTTONS 0x2000
#define HD_CURRENT_FORCE 0x2700
#define HD_NOMINAL_MAX_CONTINUOUS_FORCE 0x2604
#define HD_NOMINAL_MAX_STIFFNESS 0x2602
#define HD_USABLE_WORKSPACE_DIMENSIONS 0x2550
#define HD_FORCE_OUTPUT 0x4000
#define HD_DEVICE_BUTTON_1 (1 << 0)
#define HD_DEVICE_BUTTON_2 (1 << 1)
struct HDErrorInfo { HDushort errorCode; int internalErrorCode; HHD hHD; };
#define HD_DEVICE_ERROR(X) (((X).errorCode) != 0)
typedef HDCallbackCode (*HDSchedulerCallback)(void*);
HHD hdInitDevice(const char*); void hdDisableDevice(HHD); HDErrorInfo hdGetError();
void hdGetDoublev(HDenum, HDdouble*); void hdGetIntegerv(HDenum, HDint*); void hdSetDoublev(HDenum, const HDdouble*);
void hdEnable(HDenum); void hdBeginFrame(HHD); void hdEndFrame(HHD);
HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback, void*, HDushort);
void hdUnschedule(HDSchedulerHandle); void hdStartScheduler(); void hdStopScheduler();
