"""Co-simulation of several FMUs: the system (scene file or SSP), the master and its loop in C."""
