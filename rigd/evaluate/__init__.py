"""``rigd evaluate``: many calibrations of one dataset and their statistics (docs/evaluation.md).

- ``trials``: the settings, one calibration's task and result, a worker's state (features extracted once);
- ``runner``: where the trials run, worker processes here or ``cluster``, a Dask cluster (the [cluster] extra);
- ``protocols``: convergence (paper Fig. 19) and precision (Table 1), with ``plots``;
- ``drift``: how well ``rigd check`` tells drift from none; ``initial``: the global search from random mounts;
- ``compare``: both of the paper's protocols for several methods side by side.

Import from the modules: this file imports none of them, so ``cluster`` (Dask) and the plots are loaded only
by what uses them.
"""
