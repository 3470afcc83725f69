"""The ball's contact law fitted to the lab's own CCOR tests (the founding paper, section 3, Fig. 3).

`data` reads CCOR-against-speed points from a CSV file, `source` from the record store's `ccor`
tests of a ball lot (Store.ball_lot), `fit` fits the law's constants by least squares and
chooses a variant by leave-one-out error, `record` turns a fit into the ball-law file
(rig.physics.ball_law).
Pure: numpy, scipy and the collision model; no devices, no application, no plots.
"""
