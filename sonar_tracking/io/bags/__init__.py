"""rosbag2 bags through ``rosbags``: reading (:mod:`.reader`, also bags whose recorder was killed),
crash-safe writing (:mod:`.writer`) and repair (:mod:`.repair`)."""
from sonar_tracking.io.bags.format import MCAP_MAGIC, OPEN_TAIL, RECORDER_STATE
from sonar_tracking.io.bags.reader import (
                                           MAX_RECORD,
                                           BagMessage,
                                           BagState,
                                           BagTopic,
                                           McapScan,
                                           TruncatedBagWarning,
                                           bag_state,
                                           bag_topics,
                                           read_bag,
)
from sonar_tracking.io.bags.repair import repair
from sonar_tracking.io.bags.writer import ROS_DISTRO, BagWriteError, BagWriter, FileStats, bag_metadata, write_metadata

__all__ = ['MCAP_MAGIC', 'OPEN_TAIL', 'RECORDER_STATE', 'MAX_RECORD', 'BagMessage', 'BagState', 'BagTopic', 'McapScan',
           'TruncatedBagWarning', 'bag_state', 'bag_topics', 'read_bag', 'repair', 'ROS_DISTRO', 'BagWriteError',
           'BagWriter', 'FileStats', 'bag_metadata', 'write_metadata']
