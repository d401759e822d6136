"""`tb4 run`: a tutorial in the built-in simulator, with live progress, a picture and an optional recording."""
