"""The ball's contact law fitted to the lab's own CCOR tests (the founding paper, section 3, Fig. 3).

`data` reads CCOR-against-speed points (a CSV file or the store's ball-lot tests through
`source`), `fit` fits the law's constants by least squares and chooses a variant by
leave-one-out error, `record` turns a fit into the ball-law file (rig.physics.ball_law).
Pure: numpy, scipy and the collision model; no devices, no application, no plots.
"""
