"""Trainers that consume any fieldgen environment through its contract alone.

The contract (README, "Make your own field"): brax-style `reset(rng)` and
`step(state, action)`; `obs = concat(state, goal)`; `observation_size`,
`action_size`, `state_dim`, `goal_indices`, `episode_length`; `observation_names`
and `action_names` (trainers that split a body among controllers pick by name);
`goal_reached(state, goal)` (the success predicate, for hindsight relabelling); optionally
`success_goal_entries`, the goal's entries the success reads where it names more than the target;
`State.metrics` holds `success` and every reward term. Nothing here imports fieldgen's
internals (fieldgen.suggest, the wording of a did-you-mean hint, aside), and fieldgen/compile
never imports this package.
"""
