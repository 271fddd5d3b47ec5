"""The vocabulary every other package speaks: poses and frames, the pinhole camera's maths, shapes
and meshes, what crosses the loop each tick (`Observation`, `Command`), outcomes (`Stage`,
`Failure`, `EpisodeResult`), the seed's random streams. Imports nothing else of pickdemo."""
