"""Everything that acts (frictiongym.agents): controllers (classical and learned), evaluation, leaderboard."""
