"""runs.episode_set: a run plays the phase's fixed episode set or episodes drawn for it

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-24
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    # Runs stored before this revision all played their phase's fixed set.
    with op.batch_alter_table("runs") as batch:
        batch.add_column(
            sa.Column("episode_set", sa.String(length=8), nullable=False, server_default="fixed")
        )


def downgrade() -> None:
    with op.batch_alter_table("runs") as batch:
        batch.drop_column("episode_set")
