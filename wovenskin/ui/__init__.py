"""User interfaces: the terminal heatmap view and the guided recording session."""
