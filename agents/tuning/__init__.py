"""Tuning a classical family on the validation suite with the learned side's budget (search.py), and the
tuned twins the leaderboard runs from configs/tuned.yaml (tuned.py)."""
