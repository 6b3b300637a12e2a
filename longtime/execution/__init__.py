"""How cells run and where rows go: cells, limits, pools and Dask, the store, the run lifecycle,
calibration, searches over a parameter."""
