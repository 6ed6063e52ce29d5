"""The cameras every built field carries, by name. They live apart from the scene builders, which import
dm_control, so that the command line lists --camera's choices without loading it or mujoco, and below both
the build (fieldgen/compile) and the drawings (fieldgen/render.py), which the build imports for what each
view draws."""

TOP = "top"  # straight down, orthographic, framing the field (compile/scene.py)
FOLLOW = "follow"  # behind the agent, tracking it (compile/bodies.py)
CAMERAS = (TOP, FOLLOW)
FREE = "free"  # not the scene's: the interactive viewer's own (fieldgen view), which the mouse turns
