"""``sonar_import``: recordings of real sonars (ROS 1/2 bags, Ping Viewer logs, polar frames) into
the package's sector contract (DESIGN §4). See ``docs/importers.md`` for the conventions per format."""
from .options import ImportOptions, ProjectedOptions
from .run import ImportStats, SectorBagWriter, condition_sector, run_import
from .sources import RecordingError, open_recording, projected_to_sector
from .sweeps import Ping, Sector, SweepAssembler

__all__ = ['ImportOptions', 'ProjectedOptions', 'ImportStats', 'SectorBagWriter', 'run_import', 'condition_sector',
           'RecordingError', 'open_recording', 'projected_to_sector', 'Ping', 'Sector', 'SweepAssembler']
