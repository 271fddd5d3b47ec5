"""Running an episode: the world built from (scenario, seed), the task's parts by name, the loop that
steps it, the referee that scores it against the truth, its result, and the observers that watch it
through a view (trace, video, rerun)."""
