"""Many logs in one command (``ivslam run LOG... -o DIR``): inputs expanded into jobs
(:mod:`.inputs`), one job per log run by the same code as a single ``ivslam run``
(:mod:`.job`) sequentially, on a local process pool or on a Dask cluster (:mod:`.execute`),
and the fleet audit of the results (:mod:`.audit`); :mod:`.batch` ties them together."""
