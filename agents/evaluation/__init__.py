"""Evaluation and the leaderboard: the one evaluation loop (evaluate.py), the engine that runs its episodes
as resumable jobs on a pool or Ray (engine.py), the physical-limit reference rows (limits.py), the
statistics (stats.py), the leaderboard (leaderboard.py computes a Board, board.py; report.py renders its
text, CSV and figures; page.py its web page) and where along an episode a controller breaks
(windows.py). Imports one way: board <- report <- page <- leaderboard."""
