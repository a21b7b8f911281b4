"""prognoses: the latest prognosis per limited parameter of a breaker (issue 31)

Revision ID: 0011
Revises: 0009
"""
from alembic import op
import sqlalchemy as sa


revision = '0011'
down_revision = '0009'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'prognoses',
        sa.Column('breaker_id', sa.Integer(), nullable=False),
        sa.Column('parameter', sa.String(length=16), nullable=False),
        sa.Column('median_operations', sa.Float(), nullable=True),
        sa.Column('result', sa.JSON(), nullable=False),
        sa.Column('updated_at', sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(['breaker_id'], ['breakers.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('breaker_id', 'parameter'),
    )


def downgrade() -> None:
    op.drop_table('prognoses')
