"""A calibration's or check's progress as records: its stage and how far along it is (never words to parse).
The CLI prints them, the service's worker places them on its job's bar (rigd.api.worker)."""

from __future__ import annotations

from collections.abc import Callable
from enum import Enum


class Stage(Enum):
    HASHING = "hashing"  # the dataset's content hash (a service job's version records it)
    EDGES = "edges"  # the pairs' edges (the GMM's features), pair by pair
    REFLECTIVITY = "reflectivity"  # the pairs' images and LiDAR reflectivity (photometric costs, the search's MI)
    SEARCH = "search"  # the global search for a start, pair by pair
    OPTIMISING = "optimising"  # the solve
    ASSESSING = "assessing"  # the assessment (trust): its restarts, then the uncertainty
    OVERLAYS = "overlays"  # the pictures of the result
    AROUND = "around"  # a check: the search around the checked extrinsics

    @property
    def words(self) -> str:
        return _WORDS[self]


_WORDS = {
    Stage.HASHING: "hashing the dataset",
    Stage.EDGES: "edges of the pairs",
    Stage.REFLECTIVITY: "reflectivity and images of the pairs",
    Stage.SEARCH: "global search over the mounts",
    Stage.OPTIMISING: "optimising",
    Stage.ASSESSING: "assessing the result: restarts",
    Stage.OVERLAYS: "writing overlays",
    Stage.AROUND: "searching around the checked extrinsics",
}

# ``progress(stage, done, total)``: ``done`` of ``total`` steps of ``stage`` (pairs; 0 of 1 for a stage's start).
Progress = Callable[[Stage, int, int], None]
# ``on_iter(level, iteration, cost)``: an iteration of the optimiser's coarse-to-fine ``level`` (from 0).
OnIter = Callable[[int, int, float], None]
