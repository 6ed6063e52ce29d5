"""The version of fieldgen; build artifacts record it."""

VERSION = "0.1.0"
