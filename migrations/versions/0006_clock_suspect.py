"""clock suspect: operations dated too far after their arrival (docs/security.md, D6)

Revision ID: 0006
Revises: 0005
"""
from alembic import op
import sqlalchemy as sa


revision = '0006'
down_revision = '0005'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('operations') as batch:
        batch.add_column(sa.Column('clock_suspect', sa.Boolean(), nullable=False, server_default=sa.false()))
        batch.create_index('ix_operations_clock_suspect', ['clock_suspect'])


def downgrade() -> None:
    with op.batch_alter_table('operations') as batch:
        batch.drop_index('ix_operations_clock_suspect')
        batch.drop_column('clock_suspect')
