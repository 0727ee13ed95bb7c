"""Fitted models: the model file, the networks, editing, precision, the shipped prior."""
