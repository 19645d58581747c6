"""rosbag2 (MCAP) bags of wallbot runs: writing, reading, repairing (what a run says is ``wallbot_sim.rundata``).

Only rosbags is needed (no ROS install): the recorder node feeds :class:`BagWriter` with the
serialized bytes it receives, ``simulate --bag`` feeds it from the model (:mod:`.headless`).
"""

from wallbot_sim.bag.errors import BagError, NotABagError, UnknownTopicError

__all__ = ['BagError', 'NotABagError', 'UnknownTopicError']
