"""sim_node parameters: the plant's (``crawler_sim.core.plant.config``) plus the node's own
(pacing, outputs, recording), their descriptors, and validation to a :class:`SimConfig`.

The defaults are the seed's crawler: two bodies (a 0.5 kg head and a 1 kg tail, friction
coefficient 0.3, i.e. friction forces proportional to weight) joined by one linkage, so
``linkage_cmd`` takes ONE length. Every per-body or per-linkage list accepts one
entry meaning "the same for all", so changing the number of bodies at run time is a single
``masses`` change (``ros2 param set /crawler_sim masses "[1.0, 1.0, 1.0]"``).

The plant's values are validated by ``PlantConfig.from_values`` (the one reader, shared with
``crawler-sim replay`` and the offline runs); this module adds the node's own parameters.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Mapping

from crawler_sim.bag import topics
from crawler_sim.bag.naming import check_record_name
from crawler_sim.core.plant import config as plant
from crawler_sim.core.plant.config import PlantConfig
from crawler_sim.core.friction import RULES
from crawler_sim.core.stepper import METHODS

if TYPE_CHECKING:
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.node import Node

__all__ = ['PARAMETERS', 'OUTPUTS', 'OFF_GRID', 'SimConfig', 'descriptor', 'declare_all',
           'NODE_NAME']

#: sim_node's node name (namespaces tell several sims apart; the shared clock recognises the
#: other sims by it, ``.clock``)
NODE_NAME = 'crawler_sim'

#: the node's own parameters: name -> (default, description, range or None, read_only)
NODE_PARAMETERS: dict[str, tuple[Any, str, tuple[float, float] | None, bool]] = {
    'real_time_factor': (1.0, 'Sim seconds per wall second: 1 real time, 10 ten times faster, '
                         '0 as fast as possible', (0.0, 1000.0), False),
    'publish_clock': (True, 'Publish /clock (sim time, every publish tick) so that other '
                      'nodes, RViz and Foxglove can use_sim_time (as Gazebo does)', None, False),
    'publish_joint_states': (True, 'Publish joint_states', None, False),
    'publish_body_states': (True, 'Publish body_states', None, False),
    'publish_contact_states': (True, 'Publish contact_states (std_msgs/Int8MultiArray)',
                               None, False),
    'publish_contacts_stamped': (True, 'Publish contacts (sensor_msgs/JointState, stamped: '
                                 'name body_i, position = contact state -1/0/+1, effort = '
                                 'friction force [N])', None, False),
    'publish_odom': (True, 'Publish odom', None, False),
    'publish_markers': (True, 'Publish markers', None, False),
    'publish_diagnostics': (True, 'Publish /diagnostics', None, False),
    'publish_tf': (True, 'Publish /tf odom -> base_link (odom\'s pose, frames prefixed in a '
                   'namespace: r1/odom; not recorded)', None, False),
    'diagnostics_period': (1.0, 'Wall seconds between /diagnostics messages',
                           (0.05, 3600.0), False),
    'start_paused': (False, 'Start paused (~/pause false starts the clock), so that controllers '
                     'and recorders can connect first', None, True),
    'record': (False, 'Record inputs and outputs to an MCAP bag (crawler_sim.bag)', None, True),
    'record_dir': ('runs', 'Directory for new bags', None, True),
    'record_name': ('', 'Bag name under record_dir (empty: crawler_sim_<date>-<time>)',
                    None, True),
}

#: every parameter of sim_node: name -> (default, description, range or None, read_only)
PARAMETERS: dict[str, tuple[Any, str, tuple[float, float] | None, bool]] = {
    **{name: (default, desc, rng, False) for name, (default, desc, rng)
       in plant.PARAMETERS.items()},
    **NODE_PARAMETERS}

#: the outputs, each switched on by ``publish_<name>``, in publishing order
OUTPUTS = tuple(topics.OUTPUTS)
#: the outputs not on the publish grid (not sent with every state: ``/diagnostics`` goes out
#: every ``diagnostics_period`` from the loop); named here, so that an output added to the
#: table anywhere is on the grid unless listed
OFF_GRID = ('diagnostics',)


def descriptor(name: str) -> ParameterDescriptor:
    """The ParameterDescriptor of parameter ``name`` (description, range, read-only).

    Numbers and lists of numbers are dynamically typed: values as people type them are taken
    (``real_time_factor:=0``, an integer; ``mu:=0.4``, one number for a per-body list;
    ``masses:=[1,1,1]``, integers) and checked by ``SimConfig.from_values``, which names the
    field and its range. (rclpy's static typing refuses them: "expecting type 'DOUBLE'".)
    """
    from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
    default, desc, rng, ro = PARAMETERS[name]
    numeric = isinstance(default, (int, float, list)) and not isinstance(default, bool)
    d = ParameterDescriptor(description=desc, read_only=ro, dynamic_typing=numeric)
    if rng is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(rng[0]),
                                                     to_value=float(rng[1]), step=0.0)]
    if name == 'method':
        d.additional_constraints = 'one of: ' + ', '.join(METHODS)
    elif name == 'stiction_rule':
        d.additional_constraints = 'one of: ' + ', '.join(RULES)
    return d


def declare_all(node: Node) -> dict[str, Any]:
    """Declare every parameter on ``node`` with a value (``friction`` is the empty list, "from
    mu": a parameter declared without a value empties a whole GetParameters reply in rclpy);
    return the values (overrides applied)."""
    for name, (default, *_rest) in PARAMETERS.items():
        node.declare_parameter(name, default, descriptor(name))
    return {name: node.get_parameter_or(name).value for name in PARAMETERS}


class SimConfig(PlantConfig):
    """The node's parameters validated: the plant's (``PlantConfig``: the crawler, the actuator,
    the tick grid) and the node's own, every value also a plain attribute."""

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> SimConfig:
        """Validate a full set of sim_node parameter values; ValueError naming the field and
        the allowed range."""
        v = dict(values)
        for name, (default, _, rng, _) in NODE_PARAMETERS.items():
            if name not in v:
                raise ValueError(f'missing parameter {name}')
            if rng is not None:
                v[name] = plant.as_float(name, v[name], rng)
        for name, (default, _, _) in plant.PARAMETERS.items():
            if isinstance(default, list) and v.get(name) in (None, b''):
                v[name] = []              # an empty array of any type: "not set"
        if v['record_name']:      # a bag name stays inside record_dir: refused before the run
            check_record_name(v['record_name'])
        return super().from_values(v)

    def plant_values(self) -> dict:
        """The plant's parameter values (what a bag records and a replay reads)."""
        return {name: self.values[name] for name in plant.PARAMETERS}
