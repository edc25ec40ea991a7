"""What a robot programmer reads while and after a run (paper §6.1 life-cycle and Running
sub-FSM, §4.1 Tasks): a live view on a terminal (:mod:`.live`), plain lines otherwise
(:mod:`.plain`), the full trace in the ROS log directory (:mod:`.trace`) and a summary at the end
(:mod:`.summary`), all from the run's own messages (:mod:`.facts`, :mod:`.watch`); what a program
waits for from other nodes, when it waits long (:mod:`.waiting`).
"""

from .facts import RunFacts, TaskSpec, task_specs
from .live import LiveConsole
from .plain import PlainConsole
from .summary import build_summary, summary_lines, write_summary_json
from .trace import TraceFile
from .waiting import Waits
from .watch import Watch

__all__ = ['RunFacts', 'TaskSpec', 'task_specs', 'LiveConsole', 'PlainConsole', 'build_summary',
           'summary_lines', 'write_summary_json', 'TraceFile', 'Waits', 'Watch']
