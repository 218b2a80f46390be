"""The paper's reproduction: its numbers, the runs, the checks, the outputs and report."""
