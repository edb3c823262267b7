"""The exception hierarchy: every bad input ends here, with a message that says what to do."""


class VoxfieldError(Exception):
    """Base class for all errors voxfield reports to a user (the CLI prints them, exit 2)."""


class SceneFormatError(VoxfieldError):
    """A scene file is malformed, truncated or of an unsupported kind."""


class SceneTooLargeError(VoxfieldError):
    """A scene does not fit the octree depth or the memory budget."""


class OctreeFormatError(VoxfieldError):
    """A saved octree file is missing, corrupt or from an incompatible version."""


class CameraError(VoxfieldError):
    """A camera description is invalid (NaN, zero direction, bad field of view...)."""


class DataNotFoundError(VoxfieldError):
    """A file the user named, or the shared data folder, does not exist."""
