"""
Design studies at scale (issue #7): grids and Monte Carlo tolerance studies on Dask.

``spec`` reads and validates a sweep specification, ``models`` runs one sample of a model and
returns its scalar outputs, ``engine`` runs the samples on a Dask distributed cluster and
streams them to Parquet (resumable), ``report`` and ``plots`` summarise a finished sweep,
``verdict`` and ``advisor`` are the design tools built on it, ``cli`` the ``bb-friction``
sub-commands.  See docs/sweeps.md.
"""
