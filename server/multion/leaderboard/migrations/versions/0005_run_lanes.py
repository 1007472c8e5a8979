"""runs.num_envs and runs.lanes: a run may play several episodes at once, one per lane

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-24
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    # Runs stored before this revision have one lane, kept in the row's own columns.
    with op.batch_alter_table("runs") as batch:
        batch.add_column(sa.Column("num_envs", sa.Integer(), nullable=False, server_default="1"))
        batch.add_column(sa.Column("lanes", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("runs") as batch:
        batch.drop_column("lanes")
        batch.drop_column("num_envs")
