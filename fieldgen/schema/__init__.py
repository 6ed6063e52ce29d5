"""Field specs: YAML -> validated FieldSpec, with errors that point at the line."""

from fieldgen.schema.errors import Problem, SpecError
from fieldgen.schema.loader import bundled_fields, load_spec, resolve_spec_path
from fieldgen.schema.models import FieldSpec

__all__ = ["FieldSpec", "Problem", "SpecError", "bundled_fields", "load_spec", "resolve_spec_path"]
