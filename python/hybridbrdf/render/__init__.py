"""Rendering: the path tracer's Python side, the fit preview, the Mitsuba 3 plugin."""
