"""Farm guard: exit non-zero unless the Unity Passes render engine is registered in this Blender.

Blender silently renders with EEVEE when ``-E`` names an engine it does not know, so a farm
worker without the add-on would produce wrong frames without any error. Run this first:

    blender -b scene.blend --python-exit-code 1 --python farm/check_engine.py

One line on stdout when ``UNITY_PASSES`` is a registered render engine (Blender then goes on with
the rest of its command line, e.g. ``-f 1``); otherwise one ``error:`` line on stderr that says
how to fix the worker, and exit status 1 before anything is rendered.
The Flamenco job type (farm/flamenco/unity_passes_render.js) runs the same check.
"""

import sys

import bpy

ENGINE = "UNITY_PASSES"


def registered_engines() -> set:
    """bl_idname of every registered render engine class (imported but unregistered ones excluded)."""
    return {getattr(cls, "bl_idname", None) for cls in bpy.types.RenderEngine.__subclasses__()
            if getattr(cls, "is_registered", False)}


def main() -> int:
    if ENGINE in registered_engines():
        print(f"Unity Passes check: the {ENGINE} render engine is registered (Blender {bpy.app.version_string})")
        return 0
    print(f"error: Unity Passes check: the {ENGINE} render engine is not registered in this Blender "
          f"({bpy.app.version_string}); install and enable the Unity Passes extension on this worker "
          "(README: Render farms) - without it Blender would render with EEVEE", file=sys.stderr)
    return 1


if __name__ == "__main__" and main() != 0:
    sys.exit(1)  # only on failure: on success Blender goes on with the rest of its command line
