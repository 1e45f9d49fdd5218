"""Simulated operators: people who carry out the study's tasks through an interface.

``profiles`` holds the human timing of novices and experts (keystroke-level model
figures, reaction times, gesture durations; docs/operators.md cites the sources);
``script`` steps an operator's plan in session time (a generator that waits for time to
pass or for something to be seen); ``skin_hand`` is the skin a simulated hand touches,
rendered frame by frame on the session's clock; ``hands`` turns an operator's intent (move
along an axis, stop, a short move, the gripper) into key presses, pendant operations or
gestures with their human costs; ``operator`` looks at the scene and plans the moves of
pick-and-place and pouring.  ``wovenskin study simulate`` runs whole studies with them.
"""
