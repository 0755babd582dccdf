"""From simulation to a drive: an exported controller and the runtime that steps it on a drive's readings
(runtime.py), and the real-time loop with its safety supervisor (drive_loop.py)."""
