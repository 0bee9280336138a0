"""Signal storage: one Zarr v3 store per signal, an exclusive writer lock, a checksummed chunk journal.

:mod:`.zarr_store` is the on-disk format (and the only module that imports
``zarr``); :mod:`.lock` is the single-writer lock.
"""

from .lock import StoreLock, StoreLockedError
from .zarr_store import ChunkGrid, ChunkJournal, DiskFullError, store_status

__all__ = ["ChunkGrid", "ChunkJournal", "DiskFullError", "StoreLock", "StoreLockedError", "store_status"]
