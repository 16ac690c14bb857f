"""``sonar_import``: recordings of real sonars (ROS 1/2 bags, Ping Viewer logs, frame folders) into
the package's sector contract (DESIGN §4). See ``docs/importers.md`` for the conventions per format."""
from sonar_tracking.io.importers.options import ImportOptions, ProjectedOptions
from sonar_tracking.io.importers.readers import open_recording
from sonar_tracking.io.importers.recording import RecordingError
from sonar_tracking.io.importers.ros_bag import projected_to_sector
from sonar_tracking.io.importers.run import ImportStats, SectorBagWriter, condition_sector, run_import
from sonar_tracking.io.importers.sweeps import Ping, Sector, SweepAssembler

__all__ = ['ImportOptions', 'ProjectedOptions', 'ImportStats', 'SectorBagWriter', 'run_import', 'condition_sector',
           'RecordingError', 'open_recording', 'projected_to_sector', 'Ping', 'Sector', 'SweepAssembler']
