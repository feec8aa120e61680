"""Errors of the capture daemon; all are RigdError, so the CLI prints them and exits with an error code."""

from rigd.errors import DiskError, RigdError


class CaptureError(RigdError):
    """Base of every capture error."""


class SourceSpecError(CaptureError):
    """A ``--lidar`` / ``--camera`` source string (or the config file's ``source``) is not understood."""


class ConfigError(CaptureError):
    """The rig configuration file is missing, unreadable or has a bad value (the message names the key)."""


class SensorSilenceError(CaptureError):
    """A sensor sent nothing usable for longer than the silence timeout (the message says what it did send:
    nothing, bad packets, a stopped head, incomplete turns, turns without returns)."""


class SyncError(CaptureError):
    """The camera's and the LiDAR's times disagree for longer than the silence timeout: no pair can be shown
    to be synchronised."""


class SourceEndedError(CaptureError):
    """A recorded source (pcap, replay directory) ran out before the dataset had all its pairs."""


class DiskFullError(CaptureError, DiskError):
    """Not enough free space for the next pair; the pairs already written are complete."""


class SimRigEndedError(SourceEndedError):
    """The simulated rig has stopped at all its places and stands at the last one for good, and the dataset
    still lacks pairs: no new place will come (the pairs written are complete)."""
