"""Objects from their files: read, derive, generate C and model description, build, prove."""
