"""PARC: polygon-assisted ray casting of 3D scalar volumes (public API)."""
from data_tools import InputError, Volume
from data_tools.io import load_volume, save_volume

from .camera import Camera
from .compare import compare
from .gl import OpenGLUnavailable
from .renderer import RenderResult, render
from .scene import DirectionalLight, Isosurface, PointLight, Scene, Translucent
from .scenefile import load_scene
from .transfer import TransferFunction, load_transfer_function

__all__ = ["Camera", "compare", "DirectionalLight", "InputError", "Isosurface", "OpenGLUnavailable", "PointLight", "RenderResult", "Scene", "TransferFunction", "Translucent",
           "Volume", "load_scene", "load_transfer_function", "load_volume", "render", "save_volume"]
