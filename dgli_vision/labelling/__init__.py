"""Labelling other simulators' cloth: episodes of meshes to fold states, frame by frame.

``episodes`` reads NPZ, CloSE MATLAB and mesh-folder episodes; ``material`` finds the
cloth's material coordinates, border and corners; ``observe`` places the stickers and
tells what a camera above would see of them; ``label`` classifies and smooths each
episode; ``run`` spreads the work over processes or a Dask cluster; ``outputs`` writes
the files. See docs/simulation.md.
"""
