"""``rigd import bag``: ROS 1 ``.bag``, ROS 2 (``.db3`` folders) and MCAP recordings as rigd datasets.

- :mod:`.reader` opens the bag with ``rosbags`` (no ROS install) and yields typed messages of the named topics;
- :mod:`.images` and :mod:`.clouds` turn Image / CompressedImage, PointCloud2 / VelodyneScan into arrays;
- :mod:`.intrinsics` turns a CameraInfo into the dataset's camera;
- :mod:`.stills` finds the still moments with the capture's stillness gate (rigd.capture.gate);
- :mod:`.importer` runs both passes over the bag and writes the dataset (rigd.dataset).

docs/bags.md has the commands and what is written.
"""

from rigd.importers.bag.errors import BagError
from rigd.importers.bag.importer import BagImportOptions, ImportSummary, import_bag

__all__ = ["BagError", "BagImportOptions", "ImportSummary", "import_bag"]
