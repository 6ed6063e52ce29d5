"""Trainers that consume any fieldgen environment through its contract, and any curriculum through its own.

The contract is fieldgen.env.contract.Environment (a typing.Protocol; its docstrings say what each
member means): brax-style `reset(rng)` and `step(state, action)`; `obs = concat(state, goal)`;
`observation_size`, `action_size`, `state_dim`, `goal_indices`, `episode_length`; `observation_names`
and `action_names` (trainers that split a body among controllers pick by name); `goal_reached(state, goal)`
(the success predicate, for hindsight relabelling), `success_goal_entries` (the goal's entries the success
reads) and `success_depends_on_goal`; `name`, for messages; `variant_count`, `reset_variant(rng, variant)` and
`with_variant_weights(state, weights)` for an environment of several variants (1 for a plain field);
`kickoff_coordinates` and `with_level_weights(state, weights, keep)` for variants with kick-off points;
`reserve_worlds(worlds)` and `check_physics(overflow)` for physics of fixed capacities. `State.metrics` holds
`success` and every reward term. What a curriculum answers after each evaluation is
fieldgen.curriculum.contract (`Schedule`, `adapt`, how a batch draws its episodes). Nothing here imports
fieldgen's internals but those two contracts (and fieldgen.suggest, the wording of a message's hint), and
fieldgen/compile never imports this package.
"""
