"""An outside controller for the wall-climbing robot: the figure-8 followed with a look-ahead point and a side speed
loop (``law``), as a ROS 2 node (``node``)."""
