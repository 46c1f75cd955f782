namespace libnifalcon { class FalconFirmwareNovintSDK {}; }
