"""What is measured with the FMUs: work-precision, stability, coupling error, the scene planner, and
the parallel sweeps, CSV records and charts they share."""
