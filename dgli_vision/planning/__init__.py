"""From a verdict to an action: the next folds towards a goal state, as pick-and-place
steps in the camera frame, and their check in the simulator."""
