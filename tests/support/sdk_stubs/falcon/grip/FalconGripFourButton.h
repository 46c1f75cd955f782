namespace libnifalcon { class FalconGripFourButton {}; }
