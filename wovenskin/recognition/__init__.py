"""Gesture recognition: window data sets, models, training, evaluation, streaming recogniser and arbiter."""  # noqa: E501
