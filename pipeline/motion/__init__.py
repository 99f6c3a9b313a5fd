"""3D: motion capture, the lifter, HP smoothing, resampling, motion files, rendering."""
