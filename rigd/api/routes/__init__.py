"""One router per resource: status, jobs, capture, calibrate, datasets, extrinsics."""
