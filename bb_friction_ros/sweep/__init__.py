"""
Design studies at scale: grids and Monte Carlo tolerance studies on Dask.

``spec`` reads and validates a sweep specification, ``models`` runs one sample of a model and
returns its scalar outputs, ``engine`` runs the samples on a Dask distributed cluster and
streams them to Parquet (resumable), ``report`` and ``plots`` summarise a finished sweep,
``verdict`` and ``advisor`` are the design tools built on it, ``cli`` the ``bb-friction``
sub-commands.  See docs/sweeps.md.
"""

# Run settings shared by the engine (their defaults) and the command line (its help); here
# so that ``bb-friction --help`` does not import Dask and Arrow to show them.
# How long to wait for an existing scheduler to answer before giving up  [s]: a scheduler
# that is up answers in milliseconds; a wrong address should not cost half a minute.
CONNECT_TIMEOUT_S = 5.0
# Batches in flight per worker thread: one running, one queued so no worker waits on the
# client between tasks.
IN_FLIGHT_PER_THREAD = 2
