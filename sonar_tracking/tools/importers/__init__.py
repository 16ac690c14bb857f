"""``sonar_import``: recordings of real sonars (ROS 1/2 bags, Ping Viewer logs, polar frames) into
the package's sector contract (DESIGN §4). See ``docs/importers.md`` for the conventions per format."""
from .options import ImportOptions
from .run import ImportStats, SectorBagWriter, run_import
from .sources import RecordingError, open_recording
from .sweeps import Ping, Sector, SweepAssembler

__all__ = ['ImportOptions', 'ImportStats', 'SectorBagWriter', 'run_import', 'RecordingError', 'open_recording',
           'Ping', 'Sector', 'SweepAssembler']
