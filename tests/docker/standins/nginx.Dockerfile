# Stand-in for the official nginx:1.27 (which cannot be pulled here): Debian bookworm's nginx
# (1.22) laid out as the official image is: /etc/nginx/nginx.conf includes conf.d/*.conf (where
# docker/docker-compose.replicas.yml mounts docker/nginx.conf as default.conf), logs go to the
# container's output, and nginx runs in the foreground.
FROM multion-standin/bookworm
RUN apt-get update \
    && apt-get install -y --no-install-recommends nginx \
    && rm -rf /var/lib/apt/lists/* \
    && rm -f /etc/nginx/sites-enabled/default \
    && ln -sf /dev/stdout /var/log/nginx/access.log \
    && ln -sf /dev/stderr /var/log/nginx/error.log
EXPOSE 80
STOPSIGNAL SIGQUIT
CMD ["nginx", "-g", "daemon off;"]
