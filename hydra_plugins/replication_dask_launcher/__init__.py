"""Hydra launcher plugin of the replication suite: sweeps on a Dask cluster
(:mod:`.dask_launcher`, ``hydra/launcher=dask``)."""
