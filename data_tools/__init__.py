"""Volumes in and out: the Volume type, file readers and writers, synthetic volumes."""
from .errors import InputError
from .io import load_volume, save_volume
from .volume import Volume

__all__ = ["InputError", "Volume", "load_volume", "save_volume"]
