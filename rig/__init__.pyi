# Types of the lazily loaded public names (rig/__init__.py loads them on first use).
from rig import plans as plans
from rig.api import Bat as Bat
from rig.api import Result as Result
from rig.api import RigSpec as RigSpec
from rig.api import RunControl as RunControl
from rig.api import Verdict as Verdict
from rig.api import certify as certify
from rig.api import from_config as from_config
from rig.api import open_store as open_store
from rig.api import simulated as simulated
from rig.core.errors import RigError as RigError

__version__: str
__all__: list[str]
