"""File formats beside the core (bpy-free, never importing :mod:`blendlib.blender`).

:mod:`.shaderlab` (ShaderLab ``.shader`` import/export), :mod:`.gltf` (``.vrm``/``.glb``/``.gltf``
materials as UniVRM and UniGLTF set them), :mod:`.images` (PNG/EXR/NPY read, write and compare),
:mod:`.atomic` (the one atomic file writer).
"""
