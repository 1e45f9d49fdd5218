"""Live gesture recognition (numpy + ONNX Runtime): the streaming recogniser, the arbiter that turns its output into commands, the shipped models and the scoring of a command log."""  # noqa: E501
