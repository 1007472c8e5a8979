# Stand-in for the official postgres:16 (which cannot be pulled here): Debian bookworm's
# PostgreSQL (15) with an entrypoint that honours what docker/docker-compose.replicas.yml uses of
# the official image: POSTGRES_USER / POSTGRES_PASSWORD / POSTGRES_DB on first start, the data
# directory /var/lib/postgresql/data (a volume), and pg_isready for the health check.
FROM multion-standin/bookworm
RUN apt-get update \
    && apt-get install -y --no-install-recommends postgresql \
    && rm -rf /var/lib/apt/lists/* \
    && ln -s /usr/lib/postgresql/*/bin /usr/lib/postgresql/bin \
    && mkdir -p /var/lib/postgresql/data /var/run/postgresql \
    && chown -R postgres:postgres /var/lib/postgresql /var/run/postgresql
ENV PATH=/usr/lib/postgresql/bin:$PATH PGDATA=/var/lib/postgresql/data
COPY postgres-entrypoint.sh /usr/local/bin/docker-entrypoint.sh
VOLUME /var/lib/postgresql/data
EXPOSE 5432
ENTRYPOINT ["docker-entrypoint.sh"]
CMD ["postgres"]
