"""The Foxglove layout shipped in ``config/foxglove_layout.json``, built with the SDK's
layout model (``foxglove.layouts``) so that it stays in the app's format.

``python -m rigid_body_sim.viewer.layout [PATH]`` rewrites the file (default: the
package's ``config/foxglove_layout.json``); ``test/test_viewer_geometry.py`` checks that the
shipped file is what this builds.

Left, the 3D panel in ``world``: each body's box, ω and L arrows, Poinsot's construction
beside the first, and with an orbit the Earth, the orbit, LVLH, the Sun and the field.
Right, plots of ω (body), T and |L|, their relative drift, and the pointing error, all
from the viewer's ``/state`` channel; under them the diagnostics summary.
"""
import os
import sys

import foxglove.layouts as fl

PATH = os.path.join(os.path.dirname(__file__), '..', '..', 'config', 'foxglove_layout.json')


def _plot(title, *series):
    return fl.PlotPanel(title=title, config=fl.PlotConfig(paths=[
        fl.PlotSeries(value=f'/state.{field}', label=label) for field, label in series]))


def build() -> 'fl.Layout':
    three_d = fl.ThreeDeePanel(
        title='bodies, Poinsot construction and orbit', config=fl.ThreeDeeConfig(
            follow_tf='world', fixed_frame='world', follow_mode='follow-none',
            topics={'/scene': fl.BaseRendererSceneUpdateTopicSettings(visible=True)}))
    plots = fl.SplitContainer(direction='column', items=[
        fl.SplitItem(content=_plot('ω (base_link, rad/s)', ('omega.x', 'ω x'),
                                   ('omega.y', 'ω y'), ('omega.z', 'ω z'),
                                   ('omega_norm', '|ω|'))),
        fl.SplitItem(content=_plot('T (J) and |L| (kg·m²/s)', ('kinetic_energy', 'T'),
                                   ('angular_momentum_norm', '|L|'))),
        fl.SplitItem(content=_plot('relative drift', ('kinetic_energy_drift', 'T drift'),
                                   ('angular_momentum_drift', '|L| drift'))),
        fl.SplitItem(content=_plot('pointing error (°)',
                                   ('pointing_error_deg', 'pointing error'))),
        fl.SplitItem(content=fl.DiagnosticsSummaryPanel(
            title='diagnostics', config=fl.DiagnosticsSummaryConfig(
                topic_to_render='/diagnostics'))),
    ])
    return fl.Layout(content=fl.SplitContainer(direction='row', items=[
        fl.SplitItem(proportion=3, content=three_d), fl.SplitItem(proportion=2, content=plots)]))


def text() -> str:
    return build().to_json() + '\n'


def main(argv=None):
    from ..cli import ArgumentParser
    from ..param_spec import check_output_path
    parser = ArgumentParser(prog='python -m rigid_body_sim.viewer.layout',
                            description='Write the Foxglove layout the viewer is meant for '
                                        '(the 3D panel, the plots and the diagnostics).')
    parser.add_argument('path', nargs='?', default=os.path.normpath(PATH),
                        help='where to write it (default: %(default)s)')
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    try:
        check_output_path(args.path, 'layout path')
    except ValueError as exc:
        parser.error(str(exc))
    with open(args.path, 'w') as f:
        f.write(text())
    print(f'wrote {os.path.normpath(args.path)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
