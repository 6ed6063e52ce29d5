"""An environment from whatever names a field: a FieldSpec, a YAML path, a bundled name or a build folder."""

from __future__ import annotations

from pathlib import Path

from fieldgen.env.field import FieldEnv


def make(source, backend: str = "mjx", **kwargs) -> FieldEnv:
    """An environment from a FieldSpec, a YAML path, a bundled name or a build directory.

    Building from a spec needs dm_control; a build directory needs only mujoco.
    Keyword arguments (episode_length, auto_reset) go to FieldEnv.
    """
    from fieldgen.compile.artifact import compile_spec, load_artifact
    from fieldgen.schema import FieldSpec, load_spec, resolve_spec_path

    if backend != "mjx":
        raise ValueError(f"unknown backend {backend!r}; fieldgen environments run on 'mjx'")
    if isinstance(source, FieldSpec):
        return FieldEnv(compile_spec(source), **kwargs)
    path = Path(source) if isinstance(source, Path) else resolve_spec_path(str(source))
    if path.is_dir():
        return FieldEnv(load_artifact(path), **kwargs)
    return FieldEnv(compile_spec(load_spec(path)), **kwargs)
