"""Where stereo frames come from: cameras, recordings and the simulated rig. No Qt."""
