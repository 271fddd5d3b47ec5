"""The command line and what it runs: `run`, `bench` (parallel, gated, resumable), `perceive`,
`profile` and the HTML/PNG reports."""
