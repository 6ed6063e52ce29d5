"""The config file section a curriculum reads beside the trainers' own: named here, where the command line can know
it before JAX loads and the trainers' settings can pass over it without reading it."""

# the automatic curriculum's level sampler (curriculum.auto.Sampler), which `fieldgen train --curriculum auto` reads
# as it reads --sampler; a sweep's `sampler.KEY` is the same
SAMPLER = "sampler"
