"""The lab: what a laboratory does with a drive besides controlling it. Closed-loop drive logs
(drive_log), inverse-model identification on them (idim: the EMPS IDIM-LS and the suite's friction
structures), and the simulated closed loop checked against the measurement (closed_loop)."""
