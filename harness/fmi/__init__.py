"""FMUs over fmpy: building and locating them, one instance addressed by variable names, a single
FMU's run and its result table, the solver table the FMUs share, and `validate`."""
