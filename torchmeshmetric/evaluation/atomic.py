"""Atomic file writes (re-exported from :mod:`torchmeshmetric._atomic`, where ``data`` and ``viz`` also find them)."""

from torchmeshmetric._atomic import AtomicFileSet, atomic_file_set, atomic_write, atomic_write_with

__all__ = ["AtomicFileSet", "atomic_file_set", "atomic_write", "atomic_write_with"]
