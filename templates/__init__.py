"""The bundled designs: this folder ships as the package data of ``fabkit.bundled_templates``.

Nothing here is imported for code; :func:`fabkit.templates.bundled_folder` finds the folder with
:mod:`importlib.resources`, in a source checkout and in an installed wheel alike.
"""
