"""The cameras every built field carries, by name. They live apart from the scene builders, which
import dm_control, so that the command line lists --camera's choices without loading it or mujoco."""

TOP = "top"  # straight down, orthographic, framing the field (scene.py)
FOLLOW = "follow"  # behind the agent, tracking it (agents.py)
CAMERAS = (TOP, FOLLOW)
