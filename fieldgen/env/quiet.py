"""MJX and brax imported without their chatter: MJX prints about its optional warp backend when first
imported (brax imports it too), into whatever a command writes. The modules of this package that step
physics import this one before either."""

import contextlib
import io

with contextlib.redirect_stdout(io.StringIO()):
    import brax.envs.base  # noqa: F401
    from mujoco import mjx  # noqa: F401
