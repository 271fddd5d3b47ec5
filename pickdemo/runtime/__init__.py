"""Running an episode: the world built from (scenario, seed), the loop that steps it, the referee
that scores it against the truth, and the observers that watch it (trace, video, rerun)."""
