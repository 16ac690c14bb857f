"""Per-message cost of the nodes themselves, in process, with nobody subscribed (issue: performance)."""
from __future__ import annotations

from sonar_tracking.cli.bench import Case, register


def _sim_harbour_sector():
    """``seaking_sim``'s work for one harbour sector (simulate, convert, publish) without a fan viewer."""
    import rclpy
    from rclpy.context import Context

    from sonar_tracking.nodes.seaking_sim import SeaKingSimNode
    from sonar_tracking.ros.runtime import configure_dds, private_domain
    configure_dds()
    private_domain()
    context = Context()
    rclpy.init(context=context)
    from rclpy.parameter import Parameter
    node = SeaKingSimNode(context=context, parameter_overrides=[
        Parameter('scenario', value='scenario2'), Parameter('duration', value=0.0), Parameter('rate', value=1.0)])
    node.timer.cancel()   # the bench drives it

    def step():
        assert node._publish_next()
    return step


register(Case(name='nodes.sim_harbour_sector', group='nodes', make=_sim_harbour_sector, limit_s=0.002,
              description='seaking_sim: one harbour sector simulated, converted and published, no /sonar/fan '
              'subscriber (in process)'))
