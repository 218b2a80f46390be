"""Frequency-domain analysis of the sampled-data loop: linearization, margins, figures."""
