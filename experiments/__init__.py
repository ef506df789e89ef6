"""Experiments: configurations, the main job (`make demo`) and reports."""
