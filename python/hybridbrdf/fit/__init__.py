"""Fitting: settings, the training pool, loss, schedule, loop, record, checkpoints, ranks, hbrdf add."""
