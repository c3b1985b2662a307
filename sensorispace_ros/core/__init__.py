"""Pure science core of sensorispace_ros: numpy / scipy / scikit-learn only.

Nothing under ``core`` imports rclpy; the ROS nodes are thin adapters over it.
Module map (file name answers "where is X"):

- ``seeding``       named, independent random streams derived from one seed
- ``arm``           planar 3-segment / 4-joint arm: forward model, Jacobian, kernel
- ``retina``        pinhole retina with 6 receptors: sensation of point lights
- ``world``         light object, object-position grid, environment schedules
- ``body``          the simulated body as the naive agent sees it: sense(motor) -> sensation
- ``points_of_view``  POV sampling (paper: Jacobian-kernel walk; naive: sensory walk)
- ``compensation``  compensation search (paper: Nelder-Mead on the pose)
- ``exploration``   simulation 1 loop (events -> compensations -> POVs)
- ``hausdorff``     periodic motor metric and the POV Hausdorff matrix
- ``cca``           Curvilinear Component Analysis (scikit-learn style estimator)
- ``regularize``    equality sets and the iterative metric regularisation
- ``reach``         pruned graph, Dijkstra, motor trajectory
- ``quality``       trustworthiness, continuity, Spearman, affine residual
"""
