"""One router per resource: status, jobs, capture, calibrate, check, datasets, extrinsics."""
