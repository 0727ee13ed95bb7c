"""Files the library writes, and how: atomic writes of files and folders (a reader sees the old
file or the new one, never half of one), locks for updates in place, private scratch folders,
and the package's data folders.

Public names: :func:`atomic_write_bytes`, :func:`atomic_folder`, :func:`check_writable`,
:func:`remove_stale_temporaries`, :func:`make_parent_folder` (``files.atomic``); :func:`file_lock` and ``LOCK_WAIT_SECONDS``
(``files.locks``: a test that shortens the wait patches ``hybridbrdf.files.locks.LOCK_WAIT_SECONDS``,
the value :func:`file_lock` reads); :func:`scratch_folder`; :func:`package_data_dir`.
"""

from hybridbrdf.files.atomic import (atomic_folder, atomic_write_bytes, check_writable, make_parent_folder,
                                     remove_stale_temporaries)
from hybridbrdf.files.locks import LOCK_WAIT_SECONDS, file_lock
from hybridbrdf.files.package_data import package_data_dir
from hybridbrdf.files.scratch import scratch_folder

__all__ = ["LOCK_WAIT_SECONDS", "atomic_folder", "atomic_write_bytes", "check_writable", "file_lock",
           "make_parent_folder", "package_data_dir", "remove_stale_temporaries", "scratch_folder"]
