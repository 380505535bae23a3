"""The dashboard picture of the docs (README, docs/dashboard.md): a bundled sample episode (the Workbench one, where
both hands press) replayed in the dashboard with the default setting (pico, torch-fp32), saved once `--frames`
frames were drawn (about four seconds into the episode at the default).

    xvfb-run -a -s "-screen 0 1920x1080x24" python scripts/dashboard_picture.py [--out docs/dashboard.png]
        [--frames 120] [--scene Workbench]

Needs an X display (xvfb-run gives one). Writes over `--out`: the picture is made to be replaced.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.app.sessions.bundled import SAMPLE_DIR, sample_episodes
from touchanything.app.sessions.engine_choice import build_engine, choose, default_checkpoint
from touchanything.app.sessions.replay_session import ReplaySession
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.viz.dashboard.dashboard import Dashboard


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/dashboard.png"))
    parser.add_argument("--frames", type=int, default=120, help="frames drawn before the picture (default 120)")
    parser.add_argument("--scene", default="Workbench", help="the sample episode of this scene (default Workbench)")
    args = parser.parse_args()
    episode_dir = next(p for p in sample_episodes() if p.relative_to(SAMPLE_DIR).parts[0] == args.scene)
    choice = choose(default_checkpoint())
    with open_episode(episode_dir) as episode:
        session = ReplaySession(episode, build_engine(choice), choice).start()
        Dashboard(session).run(max_frames=args.frames, screenshot=args.out.resolve())
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
