"""PARC: polygon-assisted ray casting of 3D scalar volumes (public API).

The names below are imported on first use (PEP 562), as scikit-image does:
``import parc`` loads neither NumPy nor Numba, so the `parc` command
(`parc.console`) starts inside its own error handling, and a Ctrl-C while
the libraries load ends in one line like any other.
"""
import importlib as _importlib

#: Public name -> the module that defines it.
_WHERE = {
    "Camera": ".camera",
    "compare": ".comparison",
    "DirectionalLight": ".scene",
    "InputError": "data_tools",
    "Isosurface": ".scene",
    "OpenGLUnavailable": ".gl",
    "PointLight": ".scene",
    "RenderResult": ".renderer",
    "Scene": ".scene",
    "ShowsNothingWarning": ".scene",
    "TransferFunction": ".transfer",
    "Translucent": ".scene",
    "Volume": "data_tools",
    "load_scene": ".scenefile",
    "load_transfer_function": ".transfer",
    "load_volume": "data_tools.io",
    "render": ".renderer",
    "save_transfer_function": ".transfer",
    "save_volume": "data_tools.io",
}

__all__ = sorted(_WHERE, key=str.lower)


def __getattr__(name):
    if name == "__version__":
        # The installed distribution's, as `parc --version` says.
        from .arguments import package_version
        return package_version()
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'parc' has no attribute {name!r}")
    value = getattr(_importlib.import_module(where, __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
