"""Pure science core of sensorispace_ros: numpy / scipy / scikit-learn only.

Nothing under ``core`` imports rclpy; the ROS nodes are thin adapters over it.
Module map (file name answers "where is X"):

- ``seeding``        named, independent random streams derived from one seed
- ``arm``            planar serial arms (any chain of links, an eye at the tip)
- ``retina``, ``sensor_code``  the eye's receptors and a fixed transform of their outputs
- ``body``, ``body_description``  the body as the agent meets it: sense(motor) -> sensation
- ``world``          the object of point lights, its grid of positions, the schedule
- ``run_world``      a run's world from its configuration
- ``paper/``         the paper's analytic strategy: exploration, compensation, POVs, equality sets
- ``naive/``         the naive agent: the same from the sensorimotor flow alone
- ``hausdorff``, ``motor_loops``  periodic motor metric, POV Hausdorff matrix, loop geometry
- ``cca``, ``regularize``  Curvilinear Component Analysis and the metric regularisation
- ``intrinsic_dimension``, ``topology``  dimension and Betti numbers of a metric
- ``reach``          pruned graph, Dijkstra, motor trajectory
- ``quality``, ``sensor_grid``  how good a representation is; the true grid of sensor positions
- ``scene``          what the viewer draws, as plain geometry
- ``numpy_math``     whether NumPy's float64 math here is the C library's
"""
