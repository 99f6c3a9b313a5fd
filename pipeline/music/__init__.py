"""Music: loudness normalisation and features on the motion clock."""
