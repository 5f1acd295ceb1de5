"""``kinecal batch --register``: each measured job's result recorded in the registry as it
settles (done, or resumed from an earlier run: a result recorded already is found by its
key and not recorded twice). Simulated jobs (a study) have no robot and are left out."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

__all__ = ["BatchRecorder"]


class BatchRecorder:
    """Called with each settled `kinecal.batch.JobRecord` (module docstring)."""

    def __init__(self, jobs: list, out: Path, db: str | None) -> None:
        from kinecal.registry.store import open_registry

        self.jobs = {j.name: j for j in jobs}
        self.out, self.db = out, db
        self.added = self.known = 0
        self.failed: list[str] = []
        open_registry(db).close()  # refused before any job runs

    def __call__(self, rec: Any) -> None:
        from kinecal._files import read_json
        from kinecal.cli._registry_common import command_text, register_result
        from kinecal.errors import InputError

        job = self.jobs.get(rec.name)
        if job is None or job.simulated or rec.status not in ("done", "resumed"):
            return
        path = self.out / f"{rec.name}.json"
        files = job.data if isinstance(job.data, list) else [job.data]
        try:
            _, new = register_result(
                job.serial or job.name, self.db, read_json(path), path, model=job.model,
                base_link=job.base_link, tip_link=job.tip_link,
                inputs={f"DATA {k + 1}": f for k, f in enumerate(files)},
                on_duplicate="return", command=command_text())
        except (InputError, OSError) as exc:
            self.failed.append(f"{rec.name}: {exc}")
            return
        self.added += new
        self.known += not new

    def say(self) -> None:
        """One line on stderr: recorded, found recorded already, failed."""
        for line in self.failed:
            typer.echo(f"kinecal: error: registry: {line}", err=True)
        typer.echo(f"registry: {self.added} calibrations recorded, {self.known} recorded "
                   f"already, {len(self.failed)} not recorded", err=True)
        if self.failed:
            raise typer.Exit(1)
