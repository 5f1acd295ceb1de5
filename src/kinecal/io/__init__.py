"""Readers and writers: model files, measurement CSVs, results. Writes are atomic."""

from kinecal._files import atomic_open, write_bytes_atomic, write_text_atomic

__all__ = ["atomic_open", "write_bytes_atomic", "write_text_atomic"]
