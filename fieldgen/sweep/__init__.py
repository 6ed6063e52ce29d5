"""Sweeps: many training runs from one file (fields x algorithms x config grid x seeds), handed to this
machine's GPUs or to SLURM, and summarized over seeds once done."""
