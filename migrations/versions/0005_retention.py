"""retention: decimated previews of raw captures removed by the retention policy

Revision ID: 0005
Revises: 0004
"""
from alembic import op
import sqlalchemy as sa


revision = '0005'
down_revision = '0004'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'capture_previews',
        sa.Column('operation_id', sa.Integer(), nullable=False),
        sa.Column('pruned_at', sa.DateTime(timezone=True), nullable=False),
        sa.Column('bytes_freed', sa.BigInteger(), nullable=False),
        sa.Column('preview', sa.JSON(), nullable=False),
        sa.ForeignKeyConstraint(['operation_id'], ['operations.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('operation_id'),
    )


def downgrade() -> None:
    op.drop_table('capture_previews')
