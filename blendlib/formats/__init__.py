"""File formats beside the core (bpy-free, never importing :mod:`blendlib.blender`).

:mod:`.shaderlab` (ShaderLab ``.shader`` import/export), :mod:`.images` (PNG/EXR/NPY read,
write and compare), :mod:`.atomic` (the one atomic file writer).
"""
