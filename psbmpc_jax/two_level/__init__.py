"""The two-level MPC of Mahipala & Johansen (MED 2023; ../docs/two_level.md): a path-following NMPC
(upper level) whose course/speed references an SB-MPC (lower level) modifies against moving targets."""
