"""A training run on disk: its folder and records, training it with progress, its plots and videos,
evaluating it afterwards, and comparing algorithms by their runs."""
