"""The bundled field specs, shipped as the package data `fieldgen.fields` (read with importlib.resources)."""
