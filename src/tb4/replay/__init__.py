"""Replaying a recorded run: the input journal a simulator keeps (journal.py) and the re-simulation from it with
no DDS (engine.py), which `tb4 replay` runs."""

__all__: list[str] = []
