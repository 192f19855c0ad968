"""Process and thread machinery: how frames get rendered, never what a frame holds (bpy-free).

- :mod:`.bandprocs`: viewport frames split in two screen bands, one drawn by a helper process.
- :mod:`.scheduler`: the viewport's worker thread (a reduced frame, then the full one; stale
  work dropped as soon as a newer request comes).
- :mod:`.allocator`: glibc's allocator told to keep freed memory (processes the project owns).
- :mod:`.forked`: independent pieces of work (the advice's candidate measurements) shared with
  a forked copy of the process (Linux).

This layer imports :mod:`blendlib.core` only; the core, the formats and the explaining tools
never import it (the core's stages are handed an executor, :mod:`blendlib.core.parts`), and
the Blender layer and the command line use it.
"""
