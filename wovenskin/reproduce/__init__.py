"""``wovenskin reproduce``: the paper's evaluation regenerated in simulation, and what it lacks.

``recognition`` trains and scores the recognisers (the paper's transformer against its
BiLSTM baseline on a random split, per-window latency, confusion matrices, and the
grouped split, stream events, robustness suite and HAART real-human accuracy the paper
does not give); ``study`` runs the simulated user study and sets Tables I and II beside
the paper's; ``paper`` holds the paper's published figures; ``report`` writes the one
Markdown + HTML report with its PNGs.
"""
