"""Signal storage: one Zarr v3 store per signal, an exclusive writer lock, a checksummed chunk journal.

:mod:`.zarr_store` is the on-disk format (and the only module that imports
``zarr``), including :class:`VerifiedArray`, the reader that checks every
chunk against its recorded CRC-32 (:class:`CorruptSignalError` when one does
not match); :mod:`.lock` is the single-writer lock; :mod:`.errors` says what
went wrong on disk, naming the path; :mod:`.cache` is the cache folder
(``$SPARSELT_CACHE``).
"""

from .errors import DiskFullError
from .lock import StoreLock, StoreLockedError
from .zarr_store import ChunkGrid, ChunkJournal, CorruptSignalError, VerifiedArray, store_status

__all__ = ["ChunkGrid", "ChunkJournal", "CorruptSignalError", "DiskFullError", "StoreLock", "StoreLockedError",
           "VerifiedArray", "store_status"]
