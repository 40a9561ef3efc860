"""Batch work on Dask: many scenes, one image in bands of rows, fits, from one machine to a
cluster (``raymitsuba render SCENE... -o TEMPLATE``, ``--tiles``, ``raymitsuba fit
SCENE...``, ``raymitsuba compare TEMPLATE SCENE...``). Dask is imported only here, and
only for a cluster: a single render never loads it, nor a batch run in this process.

================  ===============================================================
module            what it owns
================  ===============================================================
``core``          :func:`run_items`: a pure per-item function over items on Dask
                  workers (or in this process), one :class:`Result` per item
``cluster``       the client: a local cluster of spawned workers on 127.0.0.1, or a
                  scheduler's address; the worker plugin (versions, threads, warm-up)
``runtime``       what every process running items shares, without Dask: the
                  versions an image depends on, Dr.Jit's threads
``tasks``         what a worker computes: a scene to image bytes or a band of rows
``render``        :func:`render_many`: parse, send, write outputs and tiles atomically
``fit``           :func:`fit_many`: one fit per scene, each to its own target
``compare``       :func:`compare_many`: one comparison per scene (or image), the
                  results to the client, which writes the report
``manifest``      the JSON-lines record of a batch, beside its outputs
``templates``     output names from a template (``out/{stem}.png``)
================  ===============================================================
"""

from raymitsuba.batch.compare import compare_many
from raymitsuba.batch.core import ItemError, Result, run_items
from raymitsuba.batch.fit import fit_many
from raymitsuba.batch.render import Item, render_many

__all__ = ["render_many", "fit_many", "compare_many", "run_items", "Result", "Item", "ItemError"]
