namespace libnifalcon { class FalconKinematicStamper {}; }
