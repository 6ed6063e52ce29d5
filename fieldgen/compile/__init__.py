"""FieldSpec -> MJCF scene -> built artifact; FieldSpec -> reward and success functions."""
